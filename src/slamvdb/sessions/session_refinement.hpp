#pragma once
// The last stage of an alignment of two sessions (session_alignment.hpp): the winning pairs'
// transform refined over all their places (ICP of the other session's voxels onto the base's,
// then point-to-plane on the base's surface), and again over each other submap's places alone.
// Internal to the alignment; its own file to keep that one readable.
//
// Why shared planes: every refinement reads the base's surface planes near its points, and
// fitting them was a large part of aligning two 3 km maps when each of the 61 refinements fitted
// its own (bench_sessions.cpp). So the planes are fitted once (in parallel), near all the other
// session's points, and read by every refinement concurrently. The ICP target stays each
// refinement's own: a per-submap ICP against the whole map's one hash of 3.2 million points took
// more CPU than building its own small one (measured, s40).
#include <cstddef>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"
#include "slamvdb/sessions/place_pair_verification.hpp"
#include "slamvdb/sessions/surface_refinement.hpp"

namespace slamvdb::sessions {

struct RefinedClouds {
  Pose T_base_other = Pose::Identity();
  double overlap = 0.0, rmse = 0.0;
};

// The other session's points of one refinement and the subsets its steps use.
struct RefinementSource {
  std::vector<Vec3d> points;   // the other session's voxels near its places, its world frame
  std::vector<Vec3d> icp;      // thinned to two cloud voxels, at most refine_points (an unbiased subset)
  std::vector<Vec3d> surface;  // a quarter of `points` or fewer, at most refine_points (unbiased)
};
// The other session's voxels within the places' radius of `other_places` (`only_submap`: that
// submap's alone).
RefinementSource refinement_source(const AlignmentSession& other, const std::set<std::size_t>& other_places,
                                   const AlignmentConfig& config, std::optional<std::size_t> only_submap = {});

// The base's side of refinements: its voxels near a set of its places (reaching 10 m beyond the
// places' radius, so that every point of the other session near its places finds its true
// neighbour) as an ICP target, and the surface planes of those near the other session's points.
// Const methods are safe to call concurrently.
class RefinementBase {
 public:
  RefinementBase(const AlignmentSession& base, const std::set<std::size_t>& base_places,
                 const AlignmentConfig& config);
  // Surface planes for the base voxels within one metre (the first ICP stage's reach, so that
  // refinements that start or end up that far from here still find them) of `source`'s points
  // moved by T_base_other. Without them, refine() skips the surface step.
  void add_planes_near(const RefinementSource& source, const Pose& T_base_other);

  // ICP stages from `start`: from 2 cloud voxels down to one refinement voxel, or, `from_refined`
  // (a start already refined on the whole map, off by the session's drift: centimetres), from one
  // cloud voxel (the per-submap refinements' ICP was most of their time).
  Pose icp(const RefinementSource& source, const Pose& start, bool from_refined = false) const;
  // The surface step from `T_after_icp` (when planes were added and config.surface_refinement),
  // and the quality of the result.
  RefinedClouds finish(const RefinementSource& source, const Pose& T_after_icp) const;
  RefinedClouds refine(const RefinementSource& source, const Pose& start, bool from_refined = false) const {
    return finish(source, icp(source, start, from_refined));
  }
  // Reads `shared`'s planes (fitted once, near every point of the other session) instead of its own.
  void use_planes_of(const RefinementBase& shared) { planes_ = shared.planes_; }
  std::size_t points() const { return points_.size(); }

 private:
  const AlignmentConfig* config_;
  std::vector<Vec3d> points_;  // base world frame
  localization::VoxelHashMap target_;
  std::shared_ptr<const SurfacePlanes> planes_;
};

// The places of the winning pairs (`only_other_submap`: of those whose other place lies in that
// other submap), base and other.
void winning_places(const AlignmentSession& other, const std::vector<VerifiedPair>& pairs,
                    const std::vector<std::size_t>& winners, std::optional<std::size_t> only_other_submap,
                    std::set<std::size_t>& base_places, std::set<std::size_t>& other_places);

}  // namespace slamvdb::sessions
