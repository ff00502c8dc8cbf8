#include "slamvdb/map/colour_basis.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

Rgb8 ColourBasis::colour(const float* embedding) const {
  const Eigen::Vector3f p = components * (Eigen::Map<const Eigen::VectorXf>(embedding, mean.size()) - mean);
  Rgb8 rgb;
  for (int c = 0; c < 3; ++c) {
    const float t = hi[c] > lo[c] ? (p[c] - lo[c]) / (hi[c] - lo[c]) : 0.5f;
    rgb[static_cast<std::size_t>(c)] = static_cast<uint8_t>(std::lround(std::clamp(t, 0.0f, 1.0f) * 255.0f));
  }
  return rgb;
}

void ColourBasis::validate(int dim) const {
  if (mean.size() != dim || components.cols() != dim)
    throw Error(fmt::format("colour basis of {}-d embeddings does not fit a {}-d map", mean.size(), dim));
  if (!mean.allFinite() || !components.allFinite() || !lo.allFinite() || !hi.allFinite())
    throw Error("colour basis holds non-finite values");
  for (int c = 0; c < 3; ++c) {
    const float n = components.row(c).norm();
    if (std::abs(n - 1.0f) > 1e-3f && n != 0.0f)  // a zero axis: a map of fewer than 3 dimensions
      throw Error(fmt::format("colour basis axis {} has length {} (expected 1)", c, n));
    if (!(lo[c] <= hi[c])) throw Error(fmt::format("colour basis range {} has lo {} above hi {}", c, lo[c], hi[c]));
  }
}

}  // namespace slamvdb
