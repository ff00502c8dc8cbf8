#pragma once
// Projective voxel-to-pixel association with occlusion, and the fusion of one feature map into
// the semantic layer (paper section 6.2.3).
#include <vector>

#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/core/feature_map.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

struct FusionParams {
  double min_depth = 0.5;   // metres; nearer voxels would cover most of the image
  double max_depth = 40.0;  // metres; farther voxels span a fraction of a feature pixel
};

// Which occupied voxel each pixel sees. Every candidate voxel is rasterised over the bounding box
// of its projected corners; a depth buffer keeps, per pixel, the voxel nearest to the camera
// (Euclidean distance from the camera centre).
struct Association {
  int width = 0, height = 0;
  std::vector<VoxelKey> voxels;     // voxels that own at least one pixel
  std::vector<int32_t> owner;       // per pixel: index into `voxels`, -1 for none
  std::vector<uint32_t> pixel_count;  // per entry of `voxels`
  std::size_t candidates = 0;       // occupied voxels inside the view volume
  std::size_t occluded = 0;         // candidates that ended with no pixel
};

struct FusionStats {
  std::size_t candidates = 0, fused_voxels = 0, occluded = 0, pixels_used = 0, pixels_total = 0;
};

class ProjectiveFusion {
 public:
  explicit ProjectiveFusion(const FusionParams& params = {}) : params_(params) {}

  // camera: intrinsics at the resolution of the image to associate with (e.g. the feature map).
  const Association& associate(const OccupancyGrid& grid, const CameraModel& camera, const Pose& T_map_camera);

  // Associates, then combines all pixels of each voxel into one observation (their mean) and
  // applies Eq. 6.1 once per voxel. Throws Error if the feature map does not match the camera
  // size or the map's embedding dimension.
  FusionStats fuse(VoxelMap& map, const FeatureMap& features, const CameraModel& camera, const Pose& T_map_camera);

 private:
  FusionParams params_;
  Association assoc_;
  std::vector<float> depth_;            // per pixel
  std::vector<VoxelKey> candidate_keys_;
  std::vector<float> accum_;            // voxels x dim
};

}  // namespace slamvdb
