#include "slamvdb/core/feature_map.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace {
const char* feature_precision_name(EmbeddingPrecision p) { return p == EmbeddingPrecision::kFloat16 ? "fp16" : "fp32"; }
}  // namespace

FeatureMap::FeatureMap(int dim, int height, int width, EmbeddingPrecision precision) {
  reset(dim, height, width, precision);
  std::fill(f32_.begin(), f32_.end(), 0.0f);
  std::fill(f16_.begin(), f16_.end(), uint16_t{0});
}

void FeatureMap::reset(int dim, int height, int width, EmbeddingPrecision precision) {
  if (dim < 0 || height < 0 || width < 0)
    throw Error(fmt::format("feature map shape {} x {} x {} has a negative side", dim, height, width));
  dim_ = dim, height_ = height, width_ = width, precision_ = precision;
  if (precision == EmbeddingPrecision::kFloat16) {
    std::vector<float>().swap(f32_);
    f16_.resize(size());
  } else {
    std::vector<uint16_t>().swap(f16_);
    f32_.resize(size());
  }
}

void FeatureMap::decode_pixel(int x, int y, float* out) const {
  kernels::decode(view(static_cast<std::size_t>(y) * width_ + x), out, static_cast<std::size_t>(dim_));
}

FeatureMap FeatureMap::converted(EmbeddingPrecision precision) const {
  if (precision == precision_) return *this;
  FeatureMap out;
  out.reset(dim_, height_, width_, precision);
  if (precision == EmbeddingPrecision::kFloat16) kernels::float_to_half(f32_.data(), out.f16_.data(), size());
  else kernels::half_to_float(f16_.data(), out.f32_.data(), size());
  return out;
}

float* FeatureMap::wrong_precision() const {
  throw Error(fmt::format("this reader needs fp32 features, but the {} x {} x {} feature map holds {}", dim_, height_,
                          width_, feature_precision_name(precision_)));
}

uint16_t* FeatureMap::wrong_half() const {
  throw Error(fmt::format("this reader needs fp16 features, but the {} x {} x {} feature map holds {}", dim_, height_,
                          width_, feature_precision_name(precision_)));
}

}  // namespace slamvdb
