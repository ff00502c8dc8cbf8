#pragma once
// A dense feature map as it travels from an encoder (or a file) into fusion. Kept apart from the
// encoder interfaces so that fusion and the map never depend on OpenCV or a network library.
#include <cstddef>
#include <vector>

namespace slamvdb {

// Per-pixel embeddings, pixel-major (H x W x C): the C values of one pixel are contiguous, which
// is what fusion reads. Files and networks that produce C x H x W are transposed on arrival.
struct FeatureMap {
  int dim = 0, height = 0, width = 0;
  std::vector<float> data;  // size height * width * dim

  FeatureMap() = default;
  FeatureMap(int dim_, int height_, int width_)
      : dim(dim_), height(height_), width(width_), data(static_cast<std::size_t>(dim_) * height_ * width_) {}
  float* pixel(int x, int y) { return data.data() + (static_cast<std::size_t>(y) * width + x) * dim; }
  const float* pixel(int x, int y) const { return data.data() + (static_cast<std::size_t>(y) * width + x) * dim; }
};

}  // namespace slamvdb
