#include "slamvdb/localization/preprocessing.hpp"

#include <absl/container/flat_hash_set.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/se3.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"

namespace slamvdb::localization {

std::vector<Vec3d> filter_points(const std::vector<Vec3f>& points, double min_range, double max_range,
                                 PointFilterStats& stats, const std::vector<float>* times,
                                 std::vector<double>* kept_times) {
  stats = {};
  stats.input = points.size();
  std::vector<Vec3d> kept;
  kept.reserve(points.size());
  if (kept_times) kept_times->clear();
  const double min2 = min_range * min_range, max2 = max_range * max_range;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3d p = points[i].cast<double>();
    if (!p.allFinite() || (times && !std::isfinite((*times)[i]))) {
      ++stats.non_finite;
      continue;
    }
    const double r2 = p.squaredNorm();
    if (r2 < min2 || r2 > max2) {
      ++stats.out_of_range;
      continue;
    }
    kept.push_back(p);
    if (times && kept_times) kept_times->push_back((*times)[i]);
  }
  return kept;
}

std::vector<double> normalise_times(const std::vector<double>& times) {
  if (times.empty()) return {};
  const auto [lo, hi] = std::minmax_element(times.begin(), times.end());
  const double span = *hi - *lo;
  std::vector<double> out(times.size(), 0.5);
  if (span > 0.0)
    for (std::size_t i = 0; i < times.size(); ++i) out[i] = (times[i] - *lo) / span;
  return out;
}

std::vector<Vec3d> deskew(const std::vector<Vec3d>& points, const std::vector<double>& times, const Pose& delta) {
  const Twist xi = se3_log(delta);
  std::vector<Vec3d> out(points.size());
  // Poses at a few hundred time steps are exact enough (a 10 Hz sweep at 10 m/s moves 1 m: 2 mm
  // per step) and save an exp per point.
  constexpr int kSteps = 512;
  std::vector<Pose> motion(kSteps + 1);
  for (int k = 0; k <= kSteps; ++k) motion[k] = se3_exp((static_cast<double>(k) / kSteps - 0.5) * xi);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const int k = static_cast<int>(std::lround(std::clamp(times[i], 0.0, 1.0) * kSteps));
    out[i] = motion[k] * points[i];
  }
  return out;
}

std::vector<Vec3d> voxel_downsample(const std::vector<Vec3d>& points, double voxel_size) {
  absl::flat_hash_set<uint64_t> seen;
  seen.reserve(points.size() / 4);
  std::vector<Vec3d> out;
  out.reserve(points.size() / 4);
  for (const Vec3d& p : points)
    if (seen.insert(pack_voxel(voxel_of(p, voxel_size))).second) out.push_back(p);
  return out;
}

}  // namespace slamvdb::localization
