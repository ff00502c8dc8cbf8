#pragma once
// The tracker's local map: a hash of voxels, each holding up to N points spread at least
// voxel_size / sqrt(N) apart, around the sensor within a radius (KISS-ICP's "voxel hash map").
// Nearest-neighbour search looks at the 27 voxels around a query, which is exact for distances
// up to one voxel edge and is all point-to-point ICP needs.
#include <absl/container/flat_hash_map.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::localization {

// A voxel of the tracker's local map (its own grid, unrelated to the semantic map's keys).
using LocalVoxel = Eigen::Vector3i;

inline LocalVoxel voxel_of(const Vec3d& p, double voxel_size) {
  return LocalVoxel(static_cast<int>(std::floor(p.x() / voxel_size)), static_cast<int>(std::floor(p.y() / voxel_size)),
                  static_cast<int>(std::floor(p.z() / voxel_size)));
}
// 21 bits per axis (+-1 048 576 voxels: +-524 km at 0.5 m), enough for a local map in the
// odometry frame; coordinates wrap beyond that, which only merges far-apart voxels' buckets.
inline uint64_t pack_voxel(const LocalVoxel& k) {
  constexpr uint64_t kMask = (1ULL << 21) - 1;
  return (static_cast<uint64_t>(static_cast<uint32_t>(k.x())) & kMask) |
         ((static_cast<uint64_t>(static_cast<uint32_t>(k.y())) & kMask) << 21) |
         ((static_cast<uint64_t>(static_cast<uint32_t>(k.z())) & kMask) << 42);
}

class VoxelHashMap {
 public:
  VoxelHashMap(double voxel_size, double max_distance, int max_points_per_voxel);

  // Adds points given in the sensor frame at T_odom_sensor, then drops voxels farther than
  // max_distance from the sensor.
  void update(const std::vector<Vec3d>& points_sensor, const Pose& T_odom_sensor);
  void add_points(const std::vector<Vec3d>& points_map);
  void remove_far_from(const Vec3d& origin);
  void clear() { voxels_.clear(); }

  // Closest map point to `query` among the 27 voxels around it; false if there is none.
  bool nearest(const Vec3d& query, Vec3d& neighbour, double& squared_distance) const;

  bool empty() const { return voxels_.empty(); }
  std::size_t num_voxels() const { return voxels_.size(); }
  std::size_t num_points() const;
  std::vector<Vec3d> points() const;
  double voxel_size() const { return voxel_size_; }

 private:
  struct Voxel {
    std::vector<Vec3d> points;
  };
  double voxel_size_, max_distance_;
  int max_points_;
  double min_spacing2_;
  absl::flat_hash_map<uint64_t, Voxel> voxels_;
};

}  // namespace slamvdb::localization
