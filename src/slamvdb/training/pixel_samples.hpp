#pragma once
// Labelled pixels sampled from feature maps for query training. Memory stays bounded: a 512 x 128
// x 192 feature map is 50 MB, so only a fixed number of labelled pixels per image is kept, as
// unit vectors in fp16 (1 KB each at 512-d; the rounding, 5e-4 relative, is far below the features'
// own noise).
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "slamvdb/core/feature_map.hpp"

namespace slamvdb {

// kUniform: pixels drawn uniformly among the image's labelled ones, so the loss is the paper's
// (LSeg's per-pixel cross-entropy) in expectation. kClassBalanced: the image's pixel budget split
// evenly over the classes present (a class with fewer pixels gives all and leaves the rest to the
// others), which trains rare classes on more pixels but biases the queries towards them.
enum class PixelSampling { kUniform, kClassBalanced };

class PixelSamples {
 public:
  explicit PixelSamples(int dim) : dim_(dim) {}

  int dim() const { return dim_; }
  std::size_t size() const { return targets_.size(); }
  std::span<const int16_t> targets() const { return targets_; }
  // Rows [first, first + count) decoded to fp32 into out (count x dim).
  void decode(std::size_t first, std::size_t count, float* out) const;
  // The fp16 rows themselves (size() x dim), and the listed rows copied into out, for callers with
  // a vectorised conversion (torch).
  const uint16_t* half_data() const { return features_.data(); }
  void gather_half(std::span<const std::size_t> rows, uint16_t* out) const;
  // Appends `feature` normalised; returns false (and keeps nothing) for a zero or non-finite vector.
  bool append(const float* feature, int16_t target);
  void reserve(std::size_t rows);
  std::size_t memory_bytes() const { return features_.capacity() * 2 + targets_.capacity() * 2; }

 private:
  int dim_;
  std::vector<uint16_t> features_;  // fp16, size() x dim, unit rows
  std::vector<int16_t> targets_;    // class index per row
};

struct SampleCounts {
  std::size_t labelled = 0;  // pixels with a target class in the image
  std::size_t sampled = 0;   // kept
  std::size_t bad = 0;       // drawn but zero or non-finite features (dropped)
};

// Draws up to `count` pixels of `features` whose target (height x width, class index or negative
// for ignored) is a class, and appends them to `out`. Deterministic for a seed.
SampleCounts sample_pixels(const FeatureMap& features, std::span<const int> targets, std::size_t count,
                           PixelSampling sampling, uint64_t seed, PixelSamples& out);

}  // namespace slamvdb
