#include "slamvdb/localization/voxel_hash_map.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>

#include "slamvdb/core/error.hpp"

namespace slamvdb::localization {

VoxelHashMap::VoxelHashMap(double voxel_size, double max_distance, int max_points_per_voxel)
    : voxel_size_(voxel_size), max_distance_(max_distance), max_points_(max_points_per_voxel) {
  if (!(voxel_size > 0.0) || !(max_distance > 0.0) || max_points_per_voxel < 1)
    throw Error(fmt::format("voxel hash map needs voxel size > 0 ({}), max distance > 0 ({}) and >= 1 point per "
                            "voxel ({})",
                            voxel_size, max_distance, max_points_per_voxel));
  const double spacing = voxel_size / std::sqrt(static_cast<double>(max_points_per_voxel));
  min_spacing2_ = spacing * spacing;
}

void VoxelHashMap::update(const std::vector<Vec3d>& points_sensor, const Pose& T_odom_sensor) {
  std::vector<Vec3d> points_map(points_sensor.size());
  std::transform(points_sensor.begin(), points_sensor.end(), points_map.begin(),
                 [&](const Vec3d& p) { return T_odom_sensor * p; });
  add_points(points_map);
  remove_far_from(T_odom_sensor.translation());
}

void VoxelHashMap::add_points(const std::vector<Vec3d>& points_map) {
  for (const Vec3d& p : points_map) {
    Voxel& voxel = voxels_[pack_voxel(voxel_of(p, voxel_size_))];
    if (static_cast<int>(voxel.points.size()) >= max_points_) continue;
    const bool crowded = std::any_of(voxel.points.begin(), voxel.points.end(),
                                     [&](const Vec3d& q) { return (q - p).squaredNorm() < min_spacing2_; });
    if (crowded) continue;
    if (voxel.points.empty()) voxel.points.reserve(max_points_);
    voxel.points.push_back(p);
  }
}

void VoxelHashMap::remove_far_from(const Vec3d& origin) {
  const double max2 = max_distance_ * max_distance_;
  absl::erase_if(voxels_, [&](const auto& entry) {
    return entry.second.points.empty() || (entry.second.points.front() - origin).squaredNorm() > max2;
  });
}

bool VoxelHashMap::nearest(const Vec3d& query, Vec3d& neighbour, double& squared_distance) const {
  const LocalVoxel c = voxel_of(query, voxel_size_);
  // Distance from the query to the lower / upper faces of its voxel, per axis: a neighbouring
  // voxel is searched only if its box can hold a point closer than the best found so far, and the
  // query's own voxel is searched first, so most of the 26 neighbours are skipped.
  const Vec3d lower = query - c.cast<double>() * voxel_size_;
  const Vec3d upper = Vec3d::Constant(voxel_size_) - lower;
  double best = std::numeric_limits<double>::infinity();
  const Vec3d* best_point = nullptr;
  const auto search = [&](int dx, int dy, int dz) {
    const auto it = voxels_.find(pack_voxel(LocalVoxel(c.x() + dx, c.y() + dy, c.z() + dz)));
    if (it == voxels_.end()) return;
    for (const Vec3d& q : it->second.points) {
      const double d2 = (q - query).squaredNorm();
      if (d2 < best) {
        best = d2;
        best_point = &q;
      }
    }
  };
  search(0, 0, 0);
  const auto gap = [&](int d, int axis) { return d < 0 ? lower[axis] : d > 0 ? upper[axis] : 0.0; };
  for (int dx = -1; dx <= 1; ++dx) {
    const double gx = gap(dx, 0);
    for (int dy = -1; dy <= 1; ++dy) {
      const double gy = gap(dy, 1);
      for (int dz = -1; dz <= 1; ++dz) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        const double gz = gap(dz, 2);
        if (gx * gx + gy * gy + gz * gz >= best) continue;
        search(dx, dy, dz);
      }
    }
  }
  if (!best_point) return false;
  neighbour = *best_point;
  squared_distance = best;
  return true;
}

std::size_t VoxelHashMap::num_points() const {
  std::size_t n = 0;
  for (const auto& [key, voxel] : voxels_) n += voxel.points.size();
  return n;
}

std::vector<Vec3d> VoxelHashMap::points() const {
  std::vector<Vec3d> out;
  out.reserve(num_points());
  for (const auto& [key, voxel] : voxels_) out.insert(out.end(), voxel.points.begin(), voxel.points.end());
  return out;
}

}  // namespace slamvdb::localization
