#pragma once
// A session's points near a set of place centres, in its world frame: what the alignment's
// refinement reads (session_alignment.cpp). Each submap's cloud is tested only against the
// centres that can reach its bounds, and submaps that none reaches are skipped, so the cost is
// that of the submaps around the places rather than every voxel of the session against every
// place (which was most of aligning two 3 km maps: bench_sessions.cpp). The result is the same
// points in the same order as the plain test of every point against every centre.
#include <cstddef>
#include <optional>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::sessions {

// The submaps' clouds (each in its submap's frame) with their bounds, computed once.
class SubmapClouds {
 public:
  SubmapClouds() = default;
  explicit SubmapClouds(std::vector<std::vector<Vec3d>> clouds);
  std::size_t size() const { return clouds_.size(); }
  const std::vector<Vec3d>& operator[](std::size_t i) const { return clouds_[i]; }

  // Every point of submap i (moved to the world by T_world_submaps[i]) within `radius`
  // (horizontally) of any of `centres` (world x, y), submaps in order and each submap's points in
  // its cloud's order. With `only_submap` (an index), that submap's points alone. Submaps in
  // parallel (TBB), the result in that order all the same.
  std::vector<Vec3d> world_points_near(const std::vector<Pose>& T_world_submaps,
                                       const std::vector<Eigen::Vector2d>& centres, double radius,
                                       std::optional<std::size_t> only_submap = {}) const;

 private:
  std::vector<std::vector<Vec3d>> clouds_;
  std::vector<Eigen::AlignedBox3d> bounds_;  // of each cloud, submap frame (empty for no points)
};

}  // namespace slamvdb::sessions
