#pragma once
// Basic geometric types shared by every part of slamvdb.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

namespace slamvdb {

using Vec3f = Eigen::Vector3f;
using Vec3d = Eigen::Vector3d;
using Pose = Eigen::Isometry3d;  // rigid transform; T_a_b maps points from frame b into frame a
using Rgb8 = std::array<uint8_t, 3>;  // a colour, red green blue

// A LiDAR scan in the sensor frame with optional per-point class labels (RELLIS-3D ids).
struct LidarScan {
  double stamp = 0.0;                // seconds
  std::vector<Vec3f> points;         // sensor frame
  std::vector<float> intensity;      // same length as points, or empty
  std::vector<uint16_t> labels;      // same length as points, or empty
};

}  // namespace slamvdb
