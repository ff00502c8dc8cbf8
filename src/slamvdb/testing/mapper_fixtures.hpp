#pragma once
// The scene, camera, features and poses the streaming mapper's unit tests share (mapper_test.cpp,
// mapper_waits_test.cpp; both also built under ThreadSanitizer as slamvdb_concurrency_tests).
#include <cmath>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/core/feature_map.hpp"

namespace slamvdb::testing {

// A wall 6 m ahead of a camera that looks along the sensor's z axis (T_lidar_camera = identity).
inline std::vector<Vec3f> wall_ahead() {
  std::vector<Vec3f> points;
  for (int x = -20; x <= 20; ++x)
    for (int y = -10; y <= 10; ++y) points.emplace_back(0.1f * x, 0.1f * y, 6.0f);
  return points;
}

// 10 x 8 pixels, 8 px focal length.
inline CameraModel small_camera() {
  CameraModel c;
  c.width = 10, c.height = 8, c.fx = 8, c.fy = 8, c.cx = 5, c.cy = 4;
  return c;
}

// `dim`-channel features of unit length (value 1) on height x width pixels.
inline FeatureMap unit_features(int dim, float value = 1.0f, int height = 8, int width = 10) {
  FeatureMap f(dim, height, width);
  for (float& v : f.values()) v = value / std::sqrt(static_cast<float>(dim));
  return f;
}

inline Pose at_x(double x) {
  Pose T = Pose::Identity();
  T.translation() = Vec3d(x, 0, 0);
  return T;
}

}  // namespace slamvdb::testing
