#pragma once
// The vector-valued voxel map of one submap, in the submap's frame: occupancy from LiDAR plus the
// semantic layer from images. It knows nothing of files, networks or sensors' formats.
#include "slamvdb/map/occupancy_grid.hpp"
#include "slamvdb/map/semantic_layer.hpp"

namespace slamvdb {

struct MapParams {
  OccupancyParams occupancy;
  SemanticParams semantic;
  // A new submap starts when the path driven since the active one started exceeds this (metres);
  // 0: one submap for the whole run. Why 50 m: see README ("Submaps and the global index").
  double submap_length = 50.0;
  // Cell edge of the global index (metres); 0: the voxel size.
  double index_cell_size = 0.0;
  double index_cell() const { return index_cell_size > 0 ? index_cell_size : occupancy.voxel_size; }
  void validate() const;  // throws Error naming the parameter
};

class VoxelMap {
 public:
  // `precision` overrides params.semantic.precision (the active submap accumulates in fp32).
  explicit VoxelMap(const MapParams& params = {});
  VoxelMap(const MapParams& params, EmbeddingPrecision precision);
  // From parts read separately (map loading); their parameters must be the map's.
  VoxelMap(const MapParams& params, OccupancyGrid occupancy, SemanticLayer semantics);

  // Occupancy update; a voxel that turns free loses its semantic entry (it no longer holds a surface).
  ScanIntegrationStats integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_submap_sensor);

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
