#include "slamvdb/synth/trajectory_sim.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "slamvdb/synth/random.hpp"

namespace slamvdb::synth {

namespace {
constexpr double kTwoPi = 2.0 * std::numbers::pi;
}

LoopPath::LoopPath(double perimeter, uint64_t seed) : perimeter_(perimeter) {
  Rng rng(seed, Stream::kPath, 0);
  a2_ = rng.uniform(0.12, 0.22);
  a3_ = rng.uniform(0.03, 0.07);
  phase2_ = rng.uniform(0.0, kTwoPi);
  phase3_ = rng.uniform(0.0, kTwoPi);

  // Arc length of the unit-radius loop, then scale it to the requested perimeter.
  constexpr int kFine = 16384;
  std::vector<double> length(kFine + 1, 0.0);
  for (int i = 1; i <= kFine; ++i) {
    const double t0 = kTwoPi * (i - 1) / kFine, t1 = kTwoPi * i / kFine;
    length[i] = length[i - 1] + 0.5 * (curve_derivative(t0).norm() + curve_derivative(t1).norm()) * (t1 - t0);
  }
  radius_ = perimeter_ / length.back();
  for (double& l : length) l *= radius_;
  centre_ = Eigen::Vector2d::Zero();
  centre_ = -curve(0.0);  // the drive starts at the origin

  const int steps = static_cast<int>(std::ceil(perimeter_ / 0.1));
  ds_ = perimeter_ / steps;
  theta_of_s_.resize(steps + 1);
  int j = 0;
  for (int i = 0; i <= steps; ++i) {
    const double s = std::min(i * ds_, length.back());
    while (j + 1 < kFine && length[j + 1] < s) ++j;
    const double f = (s - length[j]) / (length[j + 1] - length[j]);
    theta_of_s_[i] = kTwoPi * (j + std::clamp(f, 0.0, 1.0)) / kFine;
  }
  const int n = static_cast<int>(std::ceil(perimeter_ / 0.5));
  for (int i = 0; i < n; ++i) samples_.push_back(point(perimeter_ * i / n));
}

Eigen::Vector2d LoopPath::curve(double th) const {
  const double r = radius_ * (1.0 + a2_ * std::cos(2.0 * th + phase2_) + a3_ * std::cos(3.0 * th + phase3_));
  return centre_ + r * Eigen::Vector2d(std::cos(th), std::sin(th));
}

Eigen::Vector2d LoopPath::curve_derivative(double th) const {
  const double r = radius_ * (1.0 + a2_ * std::cos(2.0 * th + phase2_) + a3_ * std::cos(3.0 * th + phase3_));
  const double dr = -radius_ * (2.0 * a2_ * std::sin(2.0 * th + phase2_) + 3.0 * a3_ * std::sin(3.0 * th + phase3_));
  return dr * Eigen::Vector2d(std::cos(th), std::sin(th)) + r * Eigen::Vector2d(-std::sin(th), std::cos(th));
}

double LoopPath::theta(double s) const {
  const double lap = std::floor(s / perimeter_);
  const double u = (s - lap * perimeter_) / ds_;
  const std::size_t i = std::min(static_cast<std::size_t>(u), theta_of_s_.size() - 2);
  const double f = u - static_cast<double>(i);
  return theta_of_s_[i] + f * (theta_of_s_[i + 1] - theta_of_s_[i]);
}

Eigen::Vector2d LoopPath::point(double s) const { return curve(theta(s)); }

Eigen::Vector2d LoopPath::tangent(double s) const { return curve_derivative(theta(s)).normalized(); }

Eigen::Vector2d LoopPath::left(double s) const {
  const Eigen::Vector2d t = tangent(s);
  return {-t.y(), t.x()};
}

double LoopPath::distance(const Eigen::Vector2d& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    const Eigen::Vector2d& a = samples_[i];
    const Eigen::Vector2d& b = samples_[(i + 1) % samples_.size()];
    const Eigen::Vector2d ab = b - a;
    const double f = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    best = std::min(best, (p - (a + f * ab)).squaredNorm());
  }
  return std::sqrt(best);
}

Eigen::AlignedBox2d LoopPath::bounds() const {
  Eigen::AlignedBox2d box;
  for (const auto& p : samples_) box.extend(p);
  return box;
}

SimulatedTrajectory::SimulatedTrajectory(LoopPath path, std::shared_ptr<const Terrain> terrain, double speed,
                                         double sensor_height, double start_offset, bool reverse)
    : path_(std::move(path)),
      terrain_(std::move(terrain)),
      speed_(speed),
      sensor_height_(sensor_height),
      start_offset_(start_offset),
      direction_(reverse ? -1.0 : 1.0) {}

double SimulatedTrajectory::lateral_offset(double s) const { return 0.8 * std::sin(kTwoPi * s / 75.0); }

Pose SimulatedTrajectory::T_world_body(double elapsed) const {
  // Distance driven -> arc length on the loop (the identity for a drive from the start, forward).
  const auto loop_s = [&](double driven) { return start_offset_ + direction_ * driven; };
  const double s = speed_ * elapsed;
  auto ground_point = [&](double si) { return path_.at(loop_s(si), lateral_offset(loop_s(si))); };
  const Eigen::Vector2d xy = ground_point(s);
  constexpr double h = 0.05;
  const Eigen::Vector2d fwd = (ground_point(s + h) - ground_point(s - h)).normalized();
  const Eigen::Vector2d lft(-fwd.y(), fwd.x());
  // Roll and pitch from the ground under a 2.8 m x 1.6 m wheel footprint.
  constexpr double kHalfBase = 1.4, kHalfTrack = 0.8;
  const auto ground = [&](const Eigen::Vector2d& p) { return terrain_->height(p.x(), p.y()); };
  const double pitch_rise = ground(xy + kHalfBase * fwd) - ground(xy - kHalfBase * fwd);
  const double roll_rise = ground(xy + kHalfTrack * lft) - ground(xy - kHalfTrack * lft);
  const Vec3d x_axis = Vec3d(fwd.x(), fwd.y(), pitch_rise / (2.0 * kHalfBase)).normalized();
  const Vec3d y_guess(lft.x(), lft.y(), roll_rise / (2.0 * kHalfTrack));
  const Vec3d z_axis = x_axis.cross(y_guess).normalized();
  Pose T = Pose::Identity();
  T.linear().col(0) = x_axis;
  T.linear().col(1) = z_axis.cross(x_axis);
  T.linear().col(2) = z_axis;
  T.translation() = Vec3d(xy.x(), xy.y(), ground(xy));
  return T;
}

Pose SimulatedTrajectory::T_world_lidar(double elapsed) const {
  Pose T_body_lidar = Pose::Identity();
  T_body_lidar.linear() = Eigen::AngleAxisd(std::numbers::pi, Vec3d::UnitZ()).toRotationMatrix();
  T_body_lidar.translation() = Vec3d(0.0, 0.0, sensor_height_);
  return T_world_body(elapsed) * T_body_lidar;
}

}  // namespace slamvdb::synth
