// The tf edges give the transform between two frames through the tree, edges walked both ways.
#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "slamvdb/sensors/tf_edges.hpp"

namespace slamvdb {
namespace tf_edges_test {

Pose pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

TEST(TfEdges, ChainsThroughTheTreeBothWays) {
  TfEdges tf;
  const Pose T_base_lidar = pose(0.3, {1, 0, 2}), T_base_camera = pose(-0.2, {0.5, 0.1, 1.5});
  const Pose T_camera_optical = pose(1.0, {0, 0, 0.05});
  tf.add("base_link", "os_sensor", T_base_lidar);
  tf.add("base_link", "camera", T_base_camera);
  tf.add("camera", "camera_optical", T_camera_optical);
  tf.add("base_link", "os_sensor", pose(2.0, {9, 9, 9}));  // a pair seen again keeps its first transform
  const auto T_lidar_optical = tf.find("os_sensor", "camera_optical");
  ASSERT_TRUE(T_lidar_optical.has_value());
  EXPECT_TRUE(T_lidar_optical->isApprox(T_base_lidar.inverse() * T_base_camera * T_camera_optical, 1e-12));
  const auto T_optical_lidar = tf.find("camera_optical", "os_sensor");
  ASSERT_TRUE(T_optical_lidar.has_value());
  EXPECT_TRUE((*T_optical_lidar * *T_lidar_optical).isApprox(Pose::Identity(), 1e-12));
  EXPECT_TRUE(tf.find("os_sensor", "os_sensor")->isApprox(Pose::Identity()));
  EXPECT_FALSE(tf.find("os_sensor", "map").has_value());  // not connected
}

}  // namespace tf_edges_test
}  // namespace slamvdb
