#pragma once
// The vector-valued voxel map: occupancy from LiDAR plus the semantic layer from images. It
// knows nothing of files, networks or sensors' formats.
#include "slamvdb/map/occupancy_grid.hpp"
#include "slamvdb/map/semantic_layer.hpp"

namespace slamvdb {

struct MapParams {
  OccupancyParams occupancy;
  SemanticParams semantic;
};

class VoxelMap {
 public:
  explicit VoxelMap(const MapParams& params = {});

  // Occupancy update; a voxel that turns free loses its semantic entry (it no longer holds a surface).
  ScanIntegrationStats integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_map_sensor);

  const MapParams& params() const { return params_; }
  double voxel_size() const { return params_.occupancy.voxel_size; }
  OccupancyGrid& occupancy() { return occupancy_; }
  const OccupancyGrid& occupancy() const { return occupancy_; }
  SemanticLayer& semantics() { return semantics_; }
  const SemanticLayer& semantics() const { return semantics_; }

 private:
  MapParams params_;
  OccupancyGrid occupancy_;
  SemanticLayer semantics_;
  std::vector<VoxelKey> freed_;  // reused scratch
};

}  // namespace slamvdb
