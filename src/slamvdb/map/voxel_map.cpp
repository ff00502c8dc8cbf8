#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

VoxelMap::VoxelMap(const MapParams& params)
    : params_(params), occupancy_(params.occupancy), semantics_(params.semantic) {}

ScanIntegrationStats VoxelMap::integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_map_sensor) {
  freed_.clear();
  const ScanIntegrationStats stats = occupancy_.integrate_scan(points_sensor, T_map_sensor, &freed_);
  for (const VoxelKey& k : freed_) semantics_.erase(k);
  return stats;
}

}  // namespace slamvdb
