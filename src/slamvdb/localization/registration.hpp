#pragma once
// Robust point-to-point ICP against a VoxelHashMap (Gauss-Newton on SE(3), Geman-McClure
// weights), parallel over the points with a deterministic TBB reduction.
#include <cstddef>
#include <optional>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"

namespace slamvdb::localization {

struct IcpOptions {
  double max_correspondence_distance = 3.0;  // pairs farther apart are ignored
  double kernel_scale = 1.0;                 // Geman-McClure kappa in rho(e) = (e^2/2) / (kappa + e^2)
  int max_iterations = 500;
  double convergence = 1e-4;  // stop when the update's twist norm falls below this
  std::size_t min_correspondences = 30;
};

struct IcpResult {
  Pose T_target_source = Pose::Identity();
  int iterations = 0;
  bool converged = false;               // the update fell below `convergence`
  std::size_t correspondences = 0;      // at the last iteration
  bool enough_correspondences = false;  // never fewer than min_correspondences
};

// Aligns `source` (sensor frame) to `target`, starting from `initial_guess` (T_target_source).
IcpResult align_point_to_point(const std::vector<Vec3d>& source, const VoxelHashMap& target, const Pose& initial_guess,
                               const IcpOptions& options);

// Coarse to fine, for a guess that may be metres off (ScanContext gives a yaw only): four ICP
// stages with correspondence distances 9v, 4v, 2v and v, the first two on `coarse_target` (3v
// voxels) with the source at 4v, the last two on `fine_target` (v voxels) with the source at 2v,
// where v is `voxel`, the clouds' resolution. Shared by the loop closer and the alignment of
// sessions. Returns T_target_source, or nothing when a stage finds too few correspondences.
std::optional<Pose> align_coarse_to_fine(const std::vector<Vec3d>& source, const VoxelHashMap& coarse_target,
                                         const VoxelHashMap& fine_target, const Pose& guess, double voxel);
// Its last two stages alone (2v and v on `fine_target`, the source at 2v), for a guess already
// within about a voxel: a transform found from other evidence (the alignment of sessions guides the
// verification of most places by the transform its survey of a few found).
std::optional<Pose> align_fine(const std::vector<Vec3d>& source, const VoxelHashMap& fine_target, const Pose& guess,
                               double voxel);

struct AlignmentQuality {
  std::size_t points = 0;
  std::size_t inliers = 0;    // points with a map point within inlier_distance
  double inlier_rmse = 0.0;   // metres, over the inliers
  double inlier_fraction() const { return points ? static_cast<double>(inliers) / points : 0.0; }
};
// How well `source` at T_target_source lies on `target`.
AlignmentQuality alignment_quality(const std::vector<Vec3d>& source, const VoxelHashMap& target,
                                   const Pose& T_target_source, double inlier_distance);

}  // namespace slamvdb::localization
