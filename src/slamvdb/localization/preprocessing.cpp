#include "slamvdb/localization/preprocessing.hpp"

#include <absl/container/flat_hash_set.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
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

namespace {

// Sensor poses at evenly spaced times over a sweep, the nearest one per point: a few hundred steps
// are exact enough (a 10 Hz sweep at 10 m/s moves 1 m: 2 mm per step; at 90 deg/s it turns 9
// deg: 0.02 deg per step) and save an exp or an interpolation per point.
class SampledSweep {
 public:
  static constexpr int kSteps = 512;
  SampledSweep(double begin, double end, const std::function<Pose(double)>& T_ref_sensor)
      : begin_(begin), span_(end - begin), poses_(kSteps + 1) {
    for (int k = 0; k <= kSteps; ++k) poses_[k] = T_ref_sensor(begin + span_ * k / kSteps);
  }
  const Pose& at(double time) const {
    const double f = span_ > 0.0 ? (time - begin_) / span_ : 0.5;
    return poses_[static_cast<std::size_t>(std::lround(std::clamp(f, 0.0, 1.0) * kSteps))];
  }

 private:
  double begin_, span_;
  std::vector<Pose> poses_;
};

}  // namespace

Pose SweepMotion::T_mid_sensor(double time) const {
  const double span = time_end - time_begin;
  const double f = span > 0.0 ? std::clamp((time - time_begin) / span, 0.0, 1.0) : 0.5;
  return se3_exp((f - 0.5) * se3_log(delta));
}

SweepMotion sweep_motion(const std::vector<double>& times, const Pose& delta) {
  SweepMotion motion;
  motion.delta = delta;
  if (!times.empty()) {
    const auto [lo, hi] = std::minmax_element(times.begin(), times.end());
    motion.time_begin = *lo;
    motion.time_end = *hi;
  }
  return motion;
}

std::vector<Vec3d> deskew(const std::vector<Vec3d>& points, const std::vector<double>& times, const SweepMotion& motion) {
  const SampledSweep sweep(motion.time_begin, motion.time_end, [&](double t) { return motion.T_mid_sensor(t); });
  std::vector<Vec3d> out(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) out[i] = sweep.at(times[i]) * points[i];
  return out;
}

std::vector<Vec3f> deskew_scan(const std::vector<Vec3f>& points, const std::vector<float>& times,
                               const std::function<Pose(double)>& T_ref_sensor) {
  if (times.size() != points.size())
    throw Error(fmt::format("deskew: {} point times for {} points", times.size(), points.size()));
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const float t : times)
    if (std::isfinite(t)) lo = std::min(lo, double{t}), hi = std::max(hi, double{t});
  std::vector<Vec3f> out = points;
  if (!(lo <= hi)) return out;  // no finite time
  const SampledSweep sweep(lo, hi, T_ref_sensor);
  for (std::size_t i = 0; i < points.size(); ++i)
    if (std::isfinite(times[i]) && points[i].allFinite())
      out[i] = (sweep.at(times[i]) * points[i].cast<double>()).cast<float>();
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
