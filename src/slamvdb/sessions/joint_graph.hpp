#pragma once
// After the rigid alignment: a pose graph over the other session's submaps that corrects their
// anchors in the base's world, the base held fixed (its world is vertex 0). Each verified pair
// of the winning set measures the anchor of the other submap it was found in (its transform is
// right where it was measured, whatever the other session's drift elsewhere); consecutive
// submaps keep their stored relative poses, weighted like odometry. The result goes to
// SemanticMap::set_submap_poses: no re-integration.
// Planned (--adjust-base): the base's submaps as vertices too, with only the first fixed.
#include <cstddef>
#include <map>
#include <vector>

#include "slamvdb/localization/pose_graph.hpp"
#include "slamvdb/sessions/pair_consensus.hpp"
#include "slamvdb/sessions/place_descriptors.hpp"

namespace slamvdb::sessions {

struct JointGraphConfig {
  // Between consecutive submaps of the other session: standard deviations growing with the
  // distance between their anchors (the loop closer's odometry model).
  double chain_sigma_translation = 0.02, chain_sigma_translation_per_m = 0.01;
  double chain_sigma_rotation = 0.002, chain_sigma_rotation_per_m = 0.0005;
  double pair_sigma_translation = 0.1, pair_sigma_rotation = 0.01;  // a verified pair (robust)
  localization::PoseGraphOptions graph;
};

// T_base_submap of every submap of `other` (by id). `pairs` (and `winners`, indices into them)
// from align_sessions; submaps without a pair follow their neighbours through the chain; all
// start at T_base_other * T_other_submap.
std::map<int, Pose> correct_other_anchors(const std::vector<SessionSubmap>& other,
                                          const std::vector<VerifiedPair>& pairs,
                                          const std::vector<std::size_t>& winners, const Pose& T_base_other,
                                          const JointGraphConfig& config = {});

}  // namespace slamvdb::sessions
