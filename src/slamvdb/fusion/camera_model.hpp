#pragma once
// Pinhole camera with plumb_bob (Brown-Conrady k1 k2 p1 p2 k3) distortion, as in ROS camera_info.
#include <array>
#include <optional>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

struct CameraModel {
  int width = 0, height = 0;  // image size the intrinsics refer to
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::array<double, 5> distortion{};  // k1 k2 p1 p2 k3

  // The same camera at another resolution (e.g. the 192 x 128 feature map). Pixel centres are
  // kept aligned the way image resizing maps them: u' = (u + 0.5) * s - 0.5.
  CameraModel scaled(int new_width, int new_height) const;

  // Distorts normalised image coordinates (x/z, y/z).
  Eigen::Vector2d distort(const Eigen::Vector2d& xy) const;
  // False where the distortion polynomial has folded back (far outside the field of view).
  bool in_distortion_domain(const Eigen::Vector2d& xy) const;
  // Pixel coordinates of a point in the camera frame (z forward); nullopt behind the camera or
  // outside the distortion model's domain.
  std::optional<Eigen::Vector2d> project(const Vec3d& p_cam) const;
  bool has_distortion() const;
  void validate() const;  // throws Error on non-positive sizes or focal lengths
};

}  // namespace slamvdb
