#include "slamvdb/fusion/camera_model.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

CameraModel CameraModel::scaled(int new_width, int new_height) const {
  CameraModel c = *this;
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  c.width = new_width;
  c.height = new_height;
  c.fx = fx * sx;
  c.fy = fy * sy;
  c.cx = (cx + 0.5) * sx - 0.5;
  c.cy = (cy + 0.5) * sy - 0.5;
  return c;
}

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& xy) const {
  const auto& [k1, k2, p1, p2, k3] = distortion;
  const double x = xy.x(), y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

bool CameraModel::in_distortion_domain(const Eigen::Vector2d& xy) const {
  // The radial polynomial folds back beyond the radius where r * radial(r) stops growing: a
  // point far outside the field of view would land inside the image. Valid while
  // d/dr (r (1 + k1 r^2 + k2 r^4 + k3 r^6)) = 1 + 3 k1 r^2 + 5 k2 r^4 + 7 k3 r^6 > 0.
  const auto& [k1, k2, p1, p2, k3] = distortion;
  const double r2 = xy.squaredNorm();
  return 1.0 + r2 * (3.0 * k1 + r2 * (5.0 * k2 + r2 * 7.0 * k3)) > 0.0;
}

std::optional<Eigen::Vector2d> CameraModel::project(const Vec3d& p) const {
  if (p.z() <= 1e-6) return std::nullopt;
  const Eigen::Vector2d xy(p.x() / p.z(), p.y() / p.z());
  if (!in_distortion_domain(xy)) return std::nullopt;
  const Eigen::Vector2d d = distort(xy);
  return Eigen::Vector2d(fx * d.x() + cx, fy * d.y() + cy);
}

bool CameraModel::has_distortion() const {
  for (double k : distortion)
    if (k != 0.0) return true;
  return false;
}

void CameraModel::validate() const {
  if (width <= 0 || height <= 0 || !(fx > 0) || !(fy > 0))
    throw Error(fmt::format("invalid camera model: size {}x{}, fx {}, fy {}", width, height, fx, fy));
}

}  // namespace slamvdb
