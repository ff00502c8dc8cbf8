#include "slamvdb/core/se3.hpp"

#include <cmath>

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

}  // namespace slamvdb
