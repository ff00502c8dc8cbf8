#include "slamvdb/inference/simulated_failures.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "slamvdb/core/mix64.hpp"
#include "slamvdb/core/simulated_view.hpp"

namespace slamvdb::sim_failures {
namespace {

uint64_t key2(uint64_t a, uint64_t b) { return mix64(a ^ mix64(b)); }

double unit_uniform(uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

float lattice_gaussian(uint64_t key, int64_t i, int64_t j) {
  const uint64_t h = key2(key, static_cast<uint64_t>(i) * 0x9E3779B97F4A7C15ull ^ static_cast<uint64_t>(j));
  const double u = 1.0 - unit_uniform(mix64(h)), v = unit_uniform(mix64(h + 1));
  return static_cast<float>(std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * std::numbers::pi * v));
}

float ramp(float x, float from, float to) {  // 0 at `from`, 1 at `to` (either order)
  if (from == to) return x >= to ? 1.f : 0.f;
  return std::clamp((x - from) / (to - from), 0.f, 1.f);
}

// Standard normal CDF.
float phi(float z) { return 0.5f * std::erfc(-z * static_cast<float>(std::numbers::sqrt2 / 2)); }

}  // namespace

void smooth_field(uint64_t key, int height, int width, float cell, float* out) {
  cell = std::max(cell, 1.0f);
  // A lattice offset per key, so that blob boundaries do not sit at the same pixels in every view.
  const float ox = static_cast<float>(unit_uniform(mix64(key ^ 0x0FF5E7ull))) * cell;
  const float oy = static_cast<float>(unit_uniform(mix64(key ^ 0x0FF5E8ull))) * cell;
  const int nx = static_cast<int>(std::ceil((width + ox) / cell)) + 2, ny = static_cast<int>(std::ceil((height + oy) / cell)) + 2;
  std::vector<float> lattice(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) lattice[static_cast<std::size_t>(j) * nx + i] = lattice_gaussian(key, i, j);
  const auto smooth = [](float t) { return t * t * (3.f - 2.f * t); };
  for (int y = 0; y < height; ++y) {
    const float fy = (y + oy) / cell;
    const int j = static_cast<int>(fy);
    const float wy = smooth(fy - j);
    for (int x = 0; x < width; ++x) {
      const float fx = (x + ox) / cell;
      const int i = static_cast<int>(fx);
      const float wx = smooth(fx - i);
      const float* r0 = lattice.data() + static_cast<std::size_t>(j) * nx + i;
      const float* r1 = r0 + nx;
      const float w00 = (1 - wx) * (1 - wy), w10 = wx * (1 - wy), w01 = (1 - wx) * wy, w11 = wx * wy;
      const float v = w00 * r0[0] + w10 * r0[1] + w01 * r1[0] + w11 * r1[1];
      out[static_cast<std::size_t>(y) * width + x] = v / std::sqrt(w00 * w00 + w10 * w10 + w01 * w01 + w11 * w11);
    }
  }
}

float error_probability(const SimulatedEncoderConfig& c, double range_m, double incidence_cos, int border_px) {
  float p = c.base_error;
  if (range_m > 0) {
    p += c.range_error * ramp(static_cast<float>(range_m), c.range_near_m, c.range_far_m);
    p += c.grazing_error * ramp(1.f - static_cast<float>(incidence_cos), 0.5f, 1.f);
  }
  if (c.border_px > 0) p += c.border_error * ramp(static_cast<float>(border_px), static_cast<float>(c.border_px), 0.f);
  return p;
}

PixelErrors pixel_errors(const SimulatedEncoderConfig& c, const std::vector<int>& labels, const cv::Mat& view,
                         double stamp, uint64_t view_key) {
  const int H = c.height, W = c.width;
  const std::size_t n = static_cast<std::size_t>(H) * W;
  PixelErrors e;
  e.wrong.assign(n, 0);
  e.choice.assign(n, 0.f);
  const bool any = c.base_error > 0 || c.range_error > 0 || c.grazing_error > 0 || c.border_error > 0 ||
                   c.exposure_error > 0;
  if (!any) return e;

  // The field that decides which pixels err: a world-fixed part (the view geometry's appearance
  // channel, or an image-space field that drifts over persistence_period_s) and a per-view part.
  const float rho = std::clamp(c.persistence, 0.f, 1.f);
  std::vector<float> per_view(n), fixed(n, 0.f);
  smooth_field(key2(view_key, 0xE5505ull), H, W, c.error_cell_px, per_view.data());
  const bool has_view = !view.empty();
  if (has_view) {
    for (int y = 0; y < H; ++y) {
      const auto* g = view.ptr<cv::Vec<uint16_t, 3>>(y);
      for (int x = 0; x < W; ++x) fixed[static_cast<std::size_t>(y) * W + x] = static_cast<float>(view_appearance(g[x][2]));
    }
  } else {
    const double period = std::max(1e-3, static_cast<double>(c.persistence_period_s));
    const double t = stamp / period;
    const auto bucket = static_cast<int64_t>(std::floor(t));
    const float a = static_cast<float>(t - static_cast<double>(bucket));
    std::vector<float> next(n);
    smooth_field(key2(c.seed, 0xF1ED0000ull + static_cast<uint64_t>(bucket)), H, W, c.error_cell_px, fixed.data());
    smooth_field(key2(c.seed, 0xF1ED0000ull + static_cast<uint64_t>(bucket + 1)), H, W, c.error_cell_px, next.data());
    const float norm = 1.f / std::sqrt((1 - a) * (1 - a) + a * a);
    for (std::size_t i = 0; i < n; ++i) fixed[i] = ((1 - a) * fixed[i] + a * next[i]) * norm;
  }
  // Badly exposed regions: blobs of a per-view field above its (1 - exposure_area) quantile.
  std::vector<float> exposure;
  float exposure_threshold = 0;
  if (c.exposure_error > 0 && c.exposure_area > 0) {
    exposure.resize(n);
    smooth_field(key2(view_key, 0xE4905ull), H, W, 3.f * c.error_cell_px, exposure.data());
    // Quantile of the standard normal by bisection (the field is standard normal at every pixel).
    float lo = -6, hi = 6;
    for (int it = 0; it < 40; ++it) {
      const float mid = 0.5f * (lo + hi);
      (1.f - phi(mid) > c.exposure_area ? lo : hi) = mid;
    }
    exposure_threshold = 0.5f * (lo + hi);
  }

  const float a_fixed = std::sqrt(rho), a_view = std::sqrt(1.f - rho);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      if (labels[i] < 0) continue;  // void classes (sky) are what a network gets right
      double range = 0, incidence = 1;
      if (has_view) {
        const auto& g = view.ptr<cv::Vec<uint16_t, 3>>(y)[x];
        range = view_range(g[0]);
        incidence = view_incidence_cos(g[1]);
      }
      const int border = std::min(std::min(x, W - 1 - x), std::min(y, H - 1 - y));
      float p = error_probability(c, range, incidence, border);
      if (!exposure.empty() && exposure[i] > exposure_threshold) p += c.exposure_error;
      p = std::min(p, 0.9f);
      const float z = a_fixed * fixed[i] + a_view * per_view[i];
      if (phi(z) < p) {
        e.wrong[i] = 1;
        e.choice[i] = fixed[i];
        ++e.count;
      }
    }
  return e;
}

}  // namespace slamvdb::sim_failures
