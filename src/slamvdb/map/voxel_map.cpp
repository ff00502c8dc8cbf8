#include "slamvdb/map/voxel_map.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

void MapParams::validate() const {
  occupancy.validate();
  if (!(submap_length >= 0) || !std::isfinite(submap_length))
    throw Error(fmt::format("invalid map parameters: submap length {} must be >= 0 (0: one submap)", submap_length));
  if (!(index_cell_size >= 0) || !std::isfinite(index_cell_size))
    throw Error(fmt::format("invalid map parameters: index cell size {} must be >= 0", index_cell_size));
}

namespace {
SemanticParams with_precision(SemanticParams p, EmbeddingPrecision precision) {
  p.precision = precision;
  return p;
}
}  // namespace

VoxelMap::VoxelMap(const MapParams& params) : VoxelMap(params, params.semantic.precision) {}

VoxelMap::VoxelMap(const MapParams& params, EmbeddingPrecision precision)
    : params_(params), occupancy_(params.occupancy), semantics_(with_precision(params.semantic, precision)) {}

VoxelMap::VoxelMap(const MapParams& params, OccupancyGrid occupancy, SemanticLayer semantics)
    : params_(params), occupancy_(std::move(occupancy)), semantics_(std::move(semantics)) {
  if (occupancy_.voxel_size() != params.occupancy.voxel_size || semantics_.dim() != params.semantic.dim)
    throw Error("the parts of a voxel map have different parameters");
}

ScanIntegrationStats VoxelMap::integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_submap_sensor) {
  freed_.clear();
  const ScanIntegrationStats stats = occupancy_.integrate_scan(points_sensor, T_submap_sensor, &freed_);
  for (const VoxelKey& k : freed_) semantics_.erase(k);
  return stats;
}

}  // namespace slamvdb
