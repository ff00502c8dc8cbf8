#pragma once
// A dense feature map as it travels from an encoder (or a file) into fusion. Kept apart from the
// encoder interfaces so that fusion and the map never depend on OpenCV or a network library.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "slamvdb/core/embedding_kernels.hpp"

namespace slamvdb {

// Per-pixel embeddings, pixel-major (H x W x C): the C values of one pixel are contiguous, which
// is what fusion reads. Files and networks that produce C x H x W are transposed on arrival.
//
// Values are fp32 or fp16, as the source gave them: a network run in half precision or an '<f2'
// .npy file arrives as fp16 (half the bytes fusion has to read) and is widened only where it is
// read. The typed accessors (values(), pixel() for fp32; half_values(), half_pixel() for fp16)
// throw Error when the map holds the other precision; view(), decode_pixel() and converted() read
// either.
class FeatureMap {
 public:
  FeatureMap() = default;
  // Zero-filled.
  FeatureMap(int dim, int height, int width, EmbeddingPrecision precision = EmbeddingPrecision::kFloat32);

  // Gives the map this shape and precision, reusing its buffer when the precision is unchanged (a
  // source filling one map per frame avoids faulting in a fresh 50 MB buffer). Values are left
  // unspecified: the caller writes all of them. The other precision's buffer is released.
  void reset(int dim, int height, int width, EmbeddingPrecision precision = EmbeddingPrecision::kFloat32);

  int dim() const { return dim_; }
  int height() const { return height_; }
  int width() const { return width_; }
  EmbeddingPrecision precision() const { return precision_; }
  std::size_t pixels() const { return static_cast<std::size_t>(height_) * width_; }
  std::size_t size() const { return pixels() * static_cast<std::size_t>(dim_); }  // values
  std::size_t bytes() const { return size() * bytes_per_value(precision_); }
  bool empty() const { return size() == 0; }

  // fp32 storage.
  std::span<float> values() { return {f32_data(), size()}; }
  std::span<const float> values() const { return {f32_data(), size()}; }
  float* pixel(int x, int y) { return f32_data() + offset(x, y); }
  const float* pixel(int x, int y) const { return f32_data() + offset(x, y); }

  // fp16 storage (IEEE binary16 bit patterns).
  std::span<uint16_t> half_values() { return {f16_data(), size()}; }
  std::span<const uint16_t> half_values() const { return {f16_data(), size()}; }
  uint16_t* half_pixel(int x, int y) { return f16_data() + offset(x, y); }
  const uint16_t* half_pixel(int x, int y) const { return f16_data() + offset(x, y); }

  // Either precision: pixel `index` (y * width + x) in its storage precision, for the kernels.
  EmbeddingView view(std::size_t index) const {
    return {precision_ == EmbeddingPrecision::kFloat16 ? static_cast<const void*>(f16_.data() + index * dim_)
                                                       : static_cast<const void*>(f32_.data() + index * dim_),
            precision_};
  }
  // Pixel (x, y) as dim() fp32 values (exact: every fp16 value is an fp32 value).
  void decode_pixel(int x, int y, float* out) const;
  // A copy in `precision` (fp32 -> fp16 rounds to nearest even; fp16 -> fp32 is exact).
  FeatureMap converted(EmbeddingPrecision precision) const;

  bool operator==(const FeatureMap& other) const = default;

 private:
  std::size_t offset(int x, int y) const { return (static_cast<std::size_t>(y) * width_ + x) * dim_; }
  float* f32_data() { return precision_ == EmbeddingPrecision::kFloat32 ? f32_.data() : wrong_precision(); }
  const float* f32_data() const { return precision_ == EmbeddingPrecision::kFloat32 ? f32_.data() : wrong_precision(); }
  uint16_t* f16_data() { return precision_ == EmbeddingPrecision::kFloat16 ? f16_.data() : wrong_half(); }
  const uint16_t* f16_data() const { return precision_ == EmbeddingPrecision::kFloat16 ? f16_.data() : wrong_half(); }
  [[noreturn]] float* wrong_precision() const;
  [[noreturn]] uint16_t* wrong_half() const;

  int dim_ = 0, height_ = 0, width_ = 0;
  EmbeddingPrecision precision_ = EmbeddingPrecision::kFloat32;
  std::vector<float> f32_;     // size() values when precision_ is fp32, else empty
  std::vector<uint16_t> f16_;  // size() values when precision_ is fp16, else empty
};

}  // namespace slamvdb
