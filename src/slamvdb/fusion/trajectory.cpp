#include "slamvdb/fusion/trajectory.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace {
Eigen::Matrix3d hat(const Vec3d& w) {
  Eigen::Matrix3d W;
  W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return W;
}

// Left Jacobian of SO(3): maps the twist's rho to the translation.
Eigen::Matrix3d so3_left_jacobian(const Vec3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (theta < 1e-8) return Eigen::Matrix3d::Identity() + 0.5 * W;
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
}
}  // namespace

Pose se3_exp(const Twist& xi) {
  const Vec3d rho = xi.head<3>(), phi = xi.tail<3>();
  const double theta = phi.norm();
  Pose T = Pose::Identity();
  T.linear() = theta < 1e-12 ? Eigen::Matrix3d::Identity()
                             : Eigen::AngleAxisd(theta, phi / theta).toRotationMatrix();
  T.translation() = so3_left_jacobian(phi) * rho;
  return T;
}

Twist se3_log(const Pose& T) {
  const Eigen::AngleAxisd aa(T.linear());
  const Vec3d phi = aa.axis() * aa.angle();
  Twist xi;
  xi.tail<3>() = phi;
  xi.head<3>() = so3_left_jacobian(phi).inverse() * T.translation();
  return xi;
}

Pose interpolate_se3(const Pose& T0, const Pose& T1, double s) {
  return T0 * se3_exp(s * se3_log(T0.inverse() * T1));
}

Trajectory::Trajectory(std::vector<double> stamps, std::vector<Pose> poses)
    : stamps_(std::move(stamps)), poses_(std::move(poses)) {
  if (stamps_.size() != poses_.size())
    throw Error(fmt::format("trajectory has {} stamps but {} poses", stamps_.size(), poses_.size()));
  for (std::size_t i = 0; i < stamps_.size(); ++i) {
    if (!std::isfinite(stamps_[i])) throw Error(fmt::format("trajectory stamp {} is not finite", i));
    if (i > 0 && !(stamps_[i] > stamps_[i - 1]))
      throw Error(fmt::format("trajectory stamps out of order: stamp {} ({:.6f}) is not after stamp {} ({:.6f})",
                              i, stamps_[i], i - 1, stamps_[i - 1]));
  }
}

std::optional<Pose> Trajectory::at(double t) const {
  if (stamps_.empty() || !(t >= stamps_.front()) || !(t <= stamps_.back())) return std::nullopt;
  const auto it = std::lower_bound(stamps_.begin(), stamps_.end(), t);
  const std::size_t i1 = static_cast<std::size_t>(it - stamps_.begin());
  if (stamps_[i1] == t) return poses_[i1];
  const std::size_t i0 = i1 - 1;  // i1 > 0 because t > front here
  const double s = (t - stamps_[i0]) / (stamps_[i1] - stamps_[i0]);
  return interpolate_se3(poses_[i0], poses_[i1], s);
}

}  // namespace slamvdb
