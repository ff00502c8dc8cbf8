#pragma once
// The camera and map parameters the fusion tests share.
#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb::testing {

// A pinhole camera of width x height pixels, centred, with the proportions of the 192 x 128
// RELLIS-3D feature map (150 px focal length there).
inline CameraModel centred_camera(int width, int height) {
  CameraModel c;
  c.width = width, c.height = height;
  c.fx = c.fy = 150.0 * width / 192.0;
  c.cx = (width - 1) / 2.0, c.cy = (height - 1) / 2.0;
  return c;
}

// 0.25 m voxels with `dim`-dimensional embeddings stored in `storage`.
inline MapParams fusion_map_params(int dim, EmbeddingPrecision storage = EmbeddingPrecision::kFloat32) {
  MapParams p;
  p.occupancy.voxel_size = 0.25;
  p.semantic.dim = dim;
  p.semantic.precision = storage;
  return p;
}

}  // namespace slamvdb::testing
