#include "slamvdb/fusion/trajectory.hpp"

#include <gtest/gtest.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

Pose make_pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

TEST(Se3, ExpLogRoundTrip) {
  Twist xi;
  xi << 0.3, -1.2, 2.0, 0.4, -0.2, 0.9;
  EXPECT_TRUE(se3_log(se3_exp(xi)).isApprox(xi, 1e-9));
}

TEST(Trajectory, InterpolatesOnTheScrewMotion) {
  // A constant screw motion: the midpoint of T0..T2 must be exactly T1.
  Twist xi;
  xi << 2.0, 0.5, 0.1, 0.0, 0.1, 0.8;
  const Pose T0 = make_pose(0.2, {1, 2, 3});
  const Pose T1 = T0 * se3_exp(xi), T2 = T1 * se3_exp(xi);
  const Trajectory traj({0.0, 2.0}, {T0, T2});
  const auto mid = traj.at(1.0);
  ASSERT_TRUE(mid.has_value());
  EXPECT_TRUE(mid->matrix().isApprox(T1.matrix(), 1e-9));
  EXPECT_TRUE(traj.at(0.0)->matrix().isApprox(T0.matrix()));
  EXPECT_TRUE(traj.at(2.0)->matrix().isApprox(T2.matrix()));
}

TEST(Trajectory, OutsideRangeIsReportedNotGuessed) {
  const Trajectory traj({1.0, 2.0}, {Pose::Identity(), make_pose(0.1, {1, 0, 0})});
  EXPECT_FALSE(traj.at(0.999).has_value());
  EXPECT_FALSE(traj.at(2.001).has_value());
  EXPECT_FALSE(Trajectory().at(0.0).has_value());
}

TEST(Trajectory, RejectsOutOfOrderStamps) {
  try {
    Trajectory({0.0, 2.0, 1.0}, {Pose::Identity(), Pose::Identity(), Pose::Identity()});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("out of order"), std::string::npos);
  }
}

}  // namespace
}  // namespace slamvdb
