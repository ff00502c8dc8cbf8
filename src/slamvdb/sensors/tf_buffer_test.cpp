// The tf buffer: transforms through the tree (edges walked both ways), each dynamic edge
// interpolated between its neighbouring stamps, errors outside the recorded range.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "slamvdb/sensors/tf_buffer.hpp"

namespace slamvdb {
namespace tf_buffer_test {

Pose yaw_pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

double yaw_of(const Pose& T) { return std::atan2(T.linear()(1, 0), T.linear()(0, 0)); }

TEST(TfBuffer, StaticChainThroughTheTreeBothWays) {
  TfBuffer tf;
  const Pose T_base_lidar = yaw_pose(0.3, {1, 0, 2}), T_base_camera = yaw_pose(-0.2, {0.5, 0.1, 1.5});
  const Pose T_camera_optical = yaw_pose(1.0, {0, 0, 0.05});
  tf.add_static("base_link", "os_sensor", 0, T_base_lidar);
  tf.add_static("base_link", "camera", 0, T_base_camera);
  tf.add_static("camera", "camera_optical", 0, T_camera_optical);
  const Pose expected = T_base_lidar.inverse() * T_base_camera * T_camera_optical;
  EXPECT_TRUE(tf.lookup("os_sensor", "camera_optical", 123.0).isApprox(expected, 1e-12));
  EXPECT_TRUE((tf.lookup("camera_optical", "os_sensor", -5.0) * expected).isApprox(Pose::Identity(), 1e-12));
  EXPECT_TRUE(tf.lookup("os_sensor", "os_sensor", 0).isApprox(Pose::Identity()));
  ASSERT_TRUE(tf.chain("os_sensor", "camera_optical").has_value());
  EXPECT_TRUE(tf.chain("os_sensor", "camera_optical")->is_static());
  EXPECT_FALSE(tf.chain("os_sensor", "map").has_value());
  try {
    tf.lookup("os_sensor", "map", 0);
    ADD_FAILURE() << "not connected: expected an error";
  } catch (const TfLookupError& e) {  // names the frames and lists those seen
    EXPECT_NE(std::string(e.what()).find("'map'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("camera_optical"), std::string::npos) << e.what();
  }
}

TEST(TfBuffer, InterpolatesBetweenTwoStampsAndHoldsTheStampsExactly) {
  TfBuffer tf;
  tf.add("map", "base", 10.0, yaw_pose(0.0, {0, 0, 0}));
  tf.add("map", "base", 12.0, yaw_pose(0.8, {4, -2, 1}));
  const Pose mid = tf.lookup("map", "base", 11.0);
  EXPECT_NEAR(yaw_of(mid), 0.4, 1e-12);  // slerp about one axis: half the angle
  EXPECT_TRUE(mid.translation().isApprox(Vec3d(2, -1, 0.5), 1e-12));
  const Pose quarter = tf.lookup("map", "base", 10.5);
  EXPECT_NEAR(yaw_of(quarter), 0.2, 1e-12);
  EXPECT_TRUE(quarter.translation().isApprox(Vec3d(1, -0.5, 0.25), 1e-12));
  EXPECT_TRUE(tf.lookup("map", "base", 12.0).isApprox(yaw_pose(0.8, {4, -2, 1}), 1e-12));
  EXPECT_TRUE(tf.lookup("base", "map", 11.0).isApprox(mid.inverse(), 1e-12));
  // Stamps out of order are sorted in.
  tf.add("map", "base", 11.0, yaw_pose(0.0, {9, 9, 9}));
  EXPECT_TRUE(tf.lookup("map", "base", 11.0).translation().isApprox(Vec3d(9, 9, 9), 1e-12));
  EXPECT_FALSE(tf.chain("map", "base")->is_static());
}

TEST(TfBuffer, ChainOfStaticAndDynamicEdges) {
  // map -> odom (dynamic), odom -> base (dynamic), base -> lidar (static), base -> camera (static).
  TfBuffer tf;
  const Pose T_base_lidar = yaw_pose(0.1, {0.2, 0, 1.8}), T_base_camera = yaw_pose(-0.3, {0.4, 0.1, 1.5});
  tf.add_static("base", "lidar", 0, T_base_lidar);
  tf.add_static("base", "camera", 0, T_base_camera);
  for (int i = 0; i <= 10; ++i) {
    tf.add("map", "odom", i, yaw_pose(0.01 * i, {0.1 * i, 0, 0}));
    tf.add("odom", "base", i + 0.5, yaw_pose(0.2 * i, {1.0 * i, 0.5 * i, 0}));
  }
  const double t = 4.25;  // between 4 and 5 on map->odom, between 3.5 and 4.5 on odom->base
  const Pose T_map_odom = yaw_pose(0.0425, {0.425, 0, 0});
  const Pose T_odom_base = yaw_pose(0.2 * 3.75, {3.75, 1.875, 0});
  EXPECT_TRUE(tf.lookup("map", "lidar", t).isApprox(T_map_odom * T_odom_base * T_base_lidar, 1e-12));
  // The LiDAR-camera chain is static even though the tree moves: one transform at every time.
  const auto lidar_camera = tf.chain("lidar", "camera");
  ASSERT_TRUE(lidar_camera.has_value());
  EXPECT_TRUE(lidar_camera->is_static());
  EXPECT_TRUE(lidar_camera->at(-100).isApprox(T_base_lidar.inverse() * T_base_camera, 1e-12));
  EXPECT_FALSE(tf.chain("map", "camera")->is_static());
  // Summaries for inspect: kinds, counts, rates.
  for (const TfEdgeSummary& e : tf.edges()) {
    if (e.parent == "base") {
      EXPECT_TRUE(e.is_static);
      EXPECT_EQ(e.rate_hz(), 0.0);
    } else {
      EXPECT_FALSE(e.is_static);
      EXPECT_EQ(e.messages, 11u);
      EXPECT_NEAR(e.rate_hz(), 1.0, 1e-12);
    }
  }
  EXPECT_EQ(tf.frames(), (std::vector<std::string>{"base", "camera", "lidar", "map", "odom"}));
}

TEST(TfBuffer, OutsideTheRecordedRangeIsAnErrorBeyondTheTolerance) {
  TfBuffer tf(0.05);
  tf.add("map", "base", 10.0, yaw_pose(0.0, {0, 0, 0}));
  tf.add("map", "base", 11.0, yaw_pose(0.5, {1, 0, 0}));
  EXPECT_TRUE(tf.lookup("map", "base", 11.04).isApprox(yaw_pose(0.5, {1, 0, 0}), 1e-12));  // held, not extrapolated
  EXPECT_TRUE(tf.lookup("map", "base", 9.96).isApprox(Pose::Identity(), 1e-12));
  for (const double t : {11.2, 9.5}) {
    try {
      tf.lookup("map", "base", t);
      ADD_FAILURE() << "outside the range at " << t << ": expected an error";
    } catch (const TfLookupError& e) {  // names the frames, the time and the range
      const std::string what = e.what();
      EXPECT_NE(what.find("map -> base"), std::string::npos) << what;
      EXPECT_NE(what.find(t > 11 ? "11.200000" : "9.500000"), std::string::npos) << what;
      EXPECT_NE(what.find("from 10.000000 s to 11.000000 s"), std::string::npos) << what;
    }
  }
}

TEST(TfBuffer, AFixedJointRepublishedKeepsTwoStamps) {
  TfBuffer tf;
  const Pose T = yaw_pose(0.7, {1, 2, 3});
  for (int i = 0; i < 1000; ++i) tf.add("base", "wheel", 0.01 * i, T);
  EXPECT_EQ(tf.stored_stamps(), 2u);  // memory follows the changes, not the messages
  EXPECT_EQ(tf.edges().front().messages, 1000u);
  EXPECT_TRUE(tf.lookup("base", "wheel", 5.0).isApprox(T, 1e-12));
  EXPECT_THROW(tf.lookup("base", "wheel", 10.5), TfLookupError);  // the last stamp is 9.99
  tf.add("base", "wheel", 10.0, yaw_pose(0.0, {0, 0, 0}));  // a change: a third stamp
  EXPECT_EQ(tf.stored_stamps(), 3u);
  EXPECT_NEAR(yaw_of(tf.lookup("base", "wheel", 9.995)), 0.35, 1e-9);
}

}  // namespace tf_buffer_test
}  // namespace slamvdb
