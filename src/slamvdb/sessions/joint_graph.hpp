#pragma once
// After the rigid alignment: a pose graph over the other session's submaps that corrects their
// anchors in the base's world, the base held fixed (its world is vertex 0). Each other submap
// re-measured alone after the refinement (SubmapRefinement) measures its anchor (right where it
// was measured, whatever the other session's drift elsewhere); a submap with winning pairs but
// no refinement of its own falls back to its pairs' transforms (from the verification ICP on
// 0.5 m clouds: about 0.08 m off at the anchors, too coarse to use when refined ones exist); consecutive
// submaps keep their stored relative poses, weighted like odometry. The result goes to
// SemanticMap::set_submap_poses: no re-integration.
//
// With --adjust-base (correct_both_anchors) the base's submaps are vertices too, only its first
// (lowest id) fixed: consecutive base submaps keep their stored relative poses (the same odometry
// model), and the evidence becomes relative, between the base submap a pair (or a refinement)
// was measured against and the other submap: T_bsubmap_osubmap, which does not depend on either
// anchor. So a base whose own anchors drifted is pulled straight where the other session saw
// the same places consistently, and the other session follows the corrected base.
#include <cstddef>
#include <map>
#include <vector>

#include "slamvdb/localization/pose_graph.hpp"
#include "slamvdb/sessions/pair_consensus.hpp"
#include "slamvdb/sessions/place_descriptors.hpp"
#include "slamvdb/sessions/session_alignment.hpp"

namespace slamvdb::sessions {

struct JointGraphConfig {
  // Between consecutive submaps of the other session: standard deviations growing with the
  // distance between their anchors (the loop closer's odometry model).
  double chain_sigma_translation = 0.02, chain_sigma_translation_per_m = 0.01;
  double chain_sigma_rotation = 0.002, chain_sigma_rotation_per_m = 0.0005;
  double pair_sigma_translation = 0.1, pair_sigma_rotation = 0.01;  // a verified pair (robust)
  // A submap's refinement (robust): as fine as the refinement's voxel allows.
  double refined_sigma_translation = 0.02, refined_sigma_rotation = 0.002;
  // Off: the pairs' coarse transforms for every submap (only to measure what refining gives).
  bool use_submap_refinements = true;
  localization::PoseGraphOptions graph;
};

// T_base_submap of every submap of `other` (by id), from an alignment that succeeded
// (align_sessions); submaps without evidence follow their neighbours through the chain; all
// start at T_base_other * T_other_submap.
std::map<int, Pose> correct_other_anchors(const std::vector<SessionSubmap>& other, const SessionAlignment& alignment,
                                          const JointGraphConfig& config = {});

// Both sessions' anchors in the base's world (by id), BASE's first submap held where it is.
struct JointCorrection {
  std::map<int, Pose> base, other;
};
JointCorrection correct_both_anchors(const std::vector<SessionSubmap>& base, const std::vector<SessionSubmap>& other,
                                     const SessionAlignment& alignment, const JointGraphConfig& config = {});

}  // namespace slamvdb::sessions
