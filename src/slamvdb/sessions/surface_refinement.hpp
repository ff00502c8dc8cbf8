#pragma once
// The last step of an alignment of two sessions: point-to-plane ICP of the other session's
// voxel centres against the base's occupied surface, which each base voxel carries as a plane
// (the centroid and normal of the occupied voxels around it).
//
// Why: both maps hold voxel centres, each on its own lattice. Point-to-point ICP with a narrow
// robust kernel between two such lattices locks them together: on ground the vertical residuals
// of the right alignment take two values (-d and v - d for lattices d apart), the kernel
// down-weights the rarer, larger one and the solution walks to the lattice (measured: up to
// 0.10 m in z). Over ground of varied height the plane residuals of the right alignment average
// to zero, so this stage uses a loss that stays quadratic up to a voxel (the gate, not a kernel,
// keeps outliers out) and the fitted planes give sub-voxel surface positions where the surface
// crosses voxel layers.
#include <absl/container/flat_hash_map.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::sessions {

struct SurfaceRefinementConfig {
  double voxel = 0.25;             // metres: the maps' voxel size (of the base's points)
  double normal_radius = 0.6;      // metres: the neighbourhood of a base voxel for its plane
  std::size_t min_neighbours = 6;  // voxels (itself included) for a plane
  double max_distance = 0.5;       // metres: correspondences farther apart (plane distance) are ignored
  int max_iterations = 30;
  double convergence = 1e-6;       // the update's twist norm
  std::size_t min_correspondences = 100;
};

// The base's surface: one plane (centroid, unit normal) per base point that has enough neighbours.
class SurfacePlanes {
 public:
  // Planes only for the base points within `near_distance` (metres, per axis; some a little
  // farther) of one of `near` (the other session's points where the refinements start): the rest
  // is never matched, and a plane costs up to 125 cell look-ups. Planes in parallel (TBB), the
  // same whatever the thread count.
  SurfacePlanes(const std::vector<Vec3d>& base_points, const std::vector<Vec3d>& near,
                const SurfaceRefinementConfig& config, double near_distance = 0.5);
  // The plane of the base point nearest to `p` among the 27 cells around it (cells of one
  // voxel, so exact up to a voxel's distance); false if there is none or it has no plane.
  bool nearest(const Vec3d& p, Vec3d& centroid, Vec3d& normal) const;
  std::size_t planes() const { return planes_; }

 private:
  template <typename F>
  void for_each_near(const Vec3d& p, int reach, F&& f) const;
  // The plane of point i (centroids_[i], normals_[i]) if it has one; touches only those.
  void fit_plane(std::size_t i, const SurfaceRefinementConfig& config);
  double cell_;
  std::vector<Vec3d> points_, centroids_, normals_;  // a zero normal: no plane
  std::size_t planes_ = 0;
  absl::flat_hash_map<uint64_t, std::vector<std::size_t>> cells_;  // indices into points_
};

struct SurfaceRefinement {
  Pose T_base_other = Pose::Identity();
  int iterations = 0;
  std::size_t correspondences = 0;  // at the last iteration
  bool ok = false;                  // never fewer than min_correspondences
};

// Refines T_base_other (from `start`) so that `other_points` (other session's world) lie on the
// base's surface planes. Deterministic.
SurfaceRefinement refine_on_surface(const std::vector<Vec3d>& other_points, const SurfacePlanes& base,
                                    const Pose& start, const SurfaceRefinementConfig& config);

}  // namespace slamvdb::sessions
