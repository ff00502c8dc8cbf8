#pragma once
// Projective voxel-to-pixel association with occlusion, and the fusion of one feature map into
// the semantic layer of a submap (paper section 6.2.3).
#include <span>
#include <vector>

#include "slamvdb/core/feature_map.hpp"
#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/map/submap_merge.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

struct FusionParams {
  double min_depth = 0.5;   // metres; nearer voxels would cover most of the image
  double max_depth = 40.0;  // metres; farther voxels span a fraction of a feature pixel
  // Whether occupied voxels of the other (finished) submaps near the camera occlude the active
  // one's. Measured on the default synthetic sequence (README, "Submaps"): see the choice there.
  bool occlusion_from_other_submaps = false;
  // A frame in which more than this fraction of the pixels that land on voxels carry a non-finite
  // or all-zero feature vector is refused whole (counted); below it, such pixels are skipped.
  double max_invalid_fraction = 0.5;
};

// Which occupied voxel each pixel sees. Every candidate voxel is rasterised over the pixels its
// inscribed sphere covers; a depth buffer keeps, per pixel, the voxel nearest to the camera
// (Euclidean distance from the camera centre).
struct Association {
  static constexpr int32_t kNone = -1, kOtherSubmap = -2;
  int width = 0, height = 0;
  std::vector<VoxelKey> voxels;       // voxels of the target map that own at least one pixel
  std::vector<int32_t> owner;         // per pixel: index into `voxels`, kNone, or kOtherSubmap
  std::vector<uint32_t> pixel_count;  // per entry of `voxels`
  std::size_t candidates = 0;         // occupied target voxels inside the view volume
  std::size_t occluded = 0;           // candidates that ended with no pixel
  std::size_t pixels_other_submaps = 0;  // pixels whose nearest voxel belongs to another submap
};

struct FusionStats {
  std::size_t candidates = 0, fused_voxels = 0, occluded = 0, pixels_used = 0, pixels_total = 0;
  std::size_t pixels_other_submaps = 0;
  std::size_t pixels_nonfinite = 0, pixels_zero = 0;  // skipped feature vectors, by reason
  std::size_t frames_refused_invalid = 0;             // 1 when the frame was refused whole
  FusionStats& operator+=(const FusionStats& o);
};

class ProjectiveFusion {
 public:
  explicit ProjectiveFusion(const FusionParams& params = {}) : params_(params) {}
  const FusionParams& params() const { return params_; }

  // camera: intrinsics at the resolution of the image to associate with (e.g. the feature map).
  // occluders: other submaps whose occupied voxels take part in the depth test (not fused into).
  const Association& associate(const OccupancyGrid& grid, const CameraModel& camera, const Pose& T_submap_camera,
                               std::span<const PlacedVoxelMap> occluders = {}, const Pose& T_world_submap = {});

  // Associates, then combines all valid pixels of each voxel into one observation (their mean)
  // and applies Eq. 6.1 once per voxel. Throws Error if the feature map does not match the camera
  // size or the map's embedding dimension.
  FusionStats fuse(VoxelMap& submap, const FeatureMap& features, const CameraModel& camera,
                   const Pose& T_submap_camera, std::span<const PlacedVoxelMap> occluders = {},
                   const Pose& T_world_submap = {});

 private:
  void rasterise(const OccupancyGrid& grid, const CameraModel& camera, const Pose& T_camera_grid, bool target);

  FusionParams params_;
  Association assoc_;
  std::vector<float> depth_;  // per pixel
  std::vector<VoxelKey> candidate_keys_;
  std::vector<float> accum_;  // voxels x dim
  std::vector<uint32_t> valid_count_;
};

}  // namespace slamvdb
