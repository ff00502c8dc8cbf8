#include "slamvdb/localization/trajectory_metrics.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "slamvdb/core/error.hpp"

namespace slamvdb::localization {

namespace {
void require_same_size(const std::vector<Pose>& a, const std::vector<Pose>& b) {
  if (a.size() != b.size())
    throw Error(fmt::format("trajectory metrics: {} estimated poses but {} ground-truth poses", a.size(), b.size()));
}
double rotation_angle(const Eigen::Matrix3d& R) {
  return std::acos(std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0));
}
}  // namespace

std::vector<std::pair<std::size_t, std::size_t>> associate_by_stamp(const std::vector<double>& est,
                                                                    const std::vector<double>& truth,
                                                                    double max_difference) {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::size_t j = 0;
  for (std::size_t i = 0; i < est.size(); ++i) {
    while (j + 1 < truth.size() && truth[j + 1] <= est[i]) ++j;
    std::size_t best = j;
    if (j + 1 < truth.size() && std::abs(truth[j + 1] - est[i]) < std::abs(truth[j] - est[i])) best = j + 1;
    if (truth.empty() || std::abs(truth[best] - est[i]) > max_difference) continue;
    if (!pairs.empty() && pairs.back().second == best) continue;  // each ground-truth pose once
    pairs.emplace_back(i, best);
  }
  return pairs;
}

Pose align_umeyama(const std::vector<Pose>& estimate, const std::vector<Pose>& truth) {
  require_same_size(estimate, truth);
  if (estimate.size() < 3)
    throw Error(fmt::format("trajectory alignment needs at least 3 pose pairs, got {}", estimate.size()));
  Eigen::Matrix3Xd src(3, estimate.size()), dst(3, truth.size());
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    src.col(i) = estimate[i].translation();
    dst.col(i) = truth[i].translation();
  }
  Pose T = Pose::Identity();
  T.matrix() = Eigen::umeyama(src, dst, false);
  return T;
}

AteResult absolute_trajectory_error(const std::vector<Pose>& estimate, const std::vector<Pose>& truth) {
  AteResult r;
  r.T_truth_estimate = align_umeyama(estimate, truth);
  std::vector<double> errors;
  errors.reserve(estimate.size());
  for (std::size_t i = 0; i < estimate.size(); ++i)
    errors.push_back((r.T_truth_estimate * estimate[i].translation() - truth[i].translation()).norm());
  r.pairs = errors.size();
  double sq = 0.0;
  for (double e : errors) sq += e * e;
  r.rmse = std::sqrt(sq / errors.size());
  r.mean = std::accumulate(errors.begin(), errors.end(), 0.0) / errors.size();
  r.max = *std::max_element(errors.begin(), errors.end());
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  const std::size_t n = sorted.size();
  r.median = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  return r;
}

RpeResult relative_pose_error(const std::vector<Pose>& estimate, const std::vector<Pose>& truth, std::size_t step) {
  require_same_size(estimate, truth);
  RpeResult r;
  if (step == 0) throw Error("relative pose error: step must be >= 1");
  double st = 0.0, sr = 0.0;
  for (std::size_t i = 0; i + step < estimate.size(); ++i) {
    const Pose e = (truth[i].inverse() * truth[i + step]).inverse() * (estimate[i].inverse() * estimate[i + step]);
    st += e.translation().squaredNorm();
    const double a = rotation_angle(e.linear()) * 180.0 / std::numbers::pi;
    sr += a * a;
    ++r.pairs;
  }
  if (r.pairs > 0) {
    r.translation_rmse = std::sqrt(st / r.pairs);
    r.rotation_rmse_deg = std::sqrt(sr / r.pairs);
  }
  return r;
}

double path_length(const std::vector<Pose>& poses) {
  double d = 0.0;
  for (std::size_t i = 1; i < poses.size(); ++i) d += (poses[i].translation() - poses[i - 1].translation()).norm();
  return d;
}

std::vector<double> drift_segment_lengths(double length) {
  std::vector<double> lengths;
  if (length >= 200.0) {
    for (double l = 100.0; l <= 800.0 && l < length; l += 100.0) lengths.push_back(l);
  } else {
    for (int k = 1; k <= 5; ++k) lengths.push_back(0.1 * k * length);
  }
  return lengths;
}

DriftResult kitti_drift(const std::vector<Pose>& estimate, const std::vector<Pose>& truth, std::size_t start_step) {
  require_same_size(estimate, truth);
  DriftResult r;
  std::vector<double> dist(truth.size(), 0.0);
  for (std::size_t i = 1; i < truth.size(); ++i)
    dist[i] = dist[i - 1] + (truth[i].translation() - truth[i - 1].translation()).norm();
  if (truth.size() < 2) return r;
  r.lengths = drift_segment_lengths(dist.back());
  double t_sum = 0.0, r_sum = 0.0;
  for (std::size_t first = 0; first < truth.size(); first += std::max<std::size_t>(start_step, 1)) {
    for (const double len : r.lengths) {
      const auto it = std::upper_bound(dist.begin() + first, dist.end(), dist[first] + len);
      if (it == dist.end()) continue;
      const std::size_t last = static_cast<std::size_t>(it - dist.begin());
      const Pose dt = truth[first].inverse() * truth[last];
      const Pose de = estimate[first].inverse() * estimate[last];
      const Pose err = de.inverse() * dt;
      t_sum += err.translation().norm() / len;
      r_sum += rotation_angle(err.linear()) / len;
      ++r.segments;
    }
  }
  if (r.segments > 0) {
    r.translation_percent = 100.0 * t_sum / r.segments;
    r.rotation_deg_per_m = r_sum / r.segments * 180.0 / std::numbers::pi;
  }
  return r;
}

}  // namespace slamvdb::localization
