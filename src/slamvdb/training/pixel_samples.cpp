#include "slamvdb/training/pixel_samples.hpp"
#include "slamvdb/core/mix64.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"

namespace slamvdb {
namespace {

// The first `count` entries of `items` become a uniform sample without replacement (partial
// Fisher-Yates with our generator, mix64: std::shuffle's algorithm is implementation-defined, and
// the same seed samples the same pixels on every platform).
void choose(std::vector<int>& items, std::size_t count, uint64_t& state) {
  count = std::min(count, items.size());
  for (std::size_t i = 0; i < count; ++i) {
    state = mix64(state);
    const std::size_t j = i + static_cast<std::size_t>(state % (items.size() - i));
    std::swap(items[i], items[j]);
  }
  items.resize(count);
}

}  // namespace

void PixelSamples::decode(std::size_t first, std::size_t count, float* out) const {
  const uint16_t* in = features_.data() + first * dim_;
  for (std::size_t i = 0; i < count * dim_; ++i) out[i] = half_to_float(in[i]);
}

void PixelSamples::gather_half(std::span<const std::size_t> rows, uint16_t* out) const {
  for (std::size_t r = 0; r < rows.size(); ++r)
    std::copy_n(features_.data() + rows[r] * dim_, dim_, out + r * dim_);
}

bool PixelSamples::append(const float* feature, int16_t target) {
  double norm2 = 0;
  for (int d = 0; d < dim_; ++d) norm2 += static_cast<double>(feature[d]) * feature[d];
  if (!(norm2 > 0) || !std::isfinite(norm2)) return false;
  const float inv = static_cast<float>(1.0 / std::sqrt(norm2));
  for (int d = 0; d < dim_; ++d) features_.push_back(float_to_half(feature[d] * inv));
  targets_.push_back(target);
  return true;
}

void PixelSamples::reserve(std::size_t rows) {
  features_.reserve(rows * dim_);
  targets_.reserve(rows);
}

SampleCounts sample_pixels(const FeatureMap& features, std::span<const int> targets, std::size_t count,
                           PixelSampling sampling, uint64_t seed, PixelSamples& out) {
  const std::size_t pixels = features.pixels();
  if (targets.size() != pixels)
    throw Error(
        fmt::format("{} targets for a {} x {} feature map", targets.size(), features.width(), features.height()));
  if (features.dim() != out.dim())
    throw Error(fmt::format("{}-d features cannot join {}-d samples", features.dim(), out.dim()));
  std::map<int, std::vector<int>> by_class;  // ordered: deterministic
  SampleCounts counts;
  for (std::size_t i = 0; i < pixels; ++i)
    if (targets[i] >= 0) by_class[targets[i]].push_back(static_cast<int>(i)), ++counts.labelled;

  uint64_t state = mix64(seed);
  std::vector<int> chosen;
  if (sampling == PixelSampling::kUniform) {
    for (const auto& [k, list] : by_class) chosen.insert(chosen.end(), list.begin(), list.end());
    std::sort(chosen.begin(), chosen.end());
    choose(chosen, count, state);
    std::sort(chosen.begin(), chosen.end());  // read the map in memory order
  } else {
    // Water-filling: classes smaller than an even share give all their pixels; the rest share what is left.
    std::vector<std::pair<std::size_t, int>> sizes;
    for (const auto& [k, list] : by_class) sizes.emplace_back(list.size(), k);
    std::sort(sizes.begin(), sizes.end());
    std::size_t budget = count, left = sizes.size();
    for (const auto& [size, k] : sizes) {
      const std::size_t quota = std::min(size, budget / left);
      std::vector<int> list = by_class[k];
      choose(list, quota, state);
      chosen.insert(chosen.end(), list.begin(), list.end());
      budget -= quota;
      --left;
    }
    std::sort(chosen.begin(), chosen.end());
  }
  std::vector<float> feature(static_cast<std::size_t>(features.dim()));
  for (int i : chosen) {
    const int x = i % features.width(), y = i / features.width();
    features.decode_pixel(x, y, feature.data());  // either precision
    if (out.append(feature.data(), static_cast<int16_t>(targets[i]))) ++counts.sampled;
    else ++counts.bad;
  }
  return counts;
}

}  // namespace slamvdb
