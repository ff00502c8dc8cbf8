#pragma once
// Inputs shared by the benchmarks: the real RELLIS-3D scan from ../shared/fixtures when it is
// there (131 072 points, 77 708 returns), else a simulated 64 x 2048 scan of a ground plane and
// walls, so the benchmarks always run.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fusion/camera_model.hpp"

namespace slamvdb::bench {

inline std::filesystem::path fixture_dir() {
  return std::filesystem::path(SLAMVDB_SOURCE_DIR) / ".." / "shared" / "fixtures" / "rellis3d-000104";
}

// The simulated 64 x 2048 scan of a ground plane and walls (LiDAR frame).
inline std::vector<Vec3f> synthetic_scan() {
  std::vector<Vec3f> pts;
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0f, 0.02f);
  for (int r = 0; r < 64; ++r) {
    const double el = (-16.6 + 33.2 * r / 63.0) * M_PI / 180.0;
    for (int c = 0; c < 2048; ++c) {
      const double az = 2 * M_PI * c / 2048.0;
      const Vec3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      double t = std::numeric_limits<double>::infinity();
      if (d.z() < -1e-3) t = 1.2 / -d.z();
      if (std::abs(d.x()) > 1e-3) t = std::min(t, 30.0 / std::abs(d.x()));
      if (std::abs(d.y()) > 1e-3) t = std::min(t, 12.0 / std::abs(d.y()));
      if (std::isfinite(t)) pts.push_back((d * (t + noise(rng))).cast<float>());
    }
  }
  return pts;
}

// The real RELLIS-3D scan (LiDAR frame), returns at the origin (no return) removed, as the map would
// drop them; empty when the fixture is not there.
inline std::vector<Vec3f> real_scan() {
  std::vector<Vec3f> pts;
  std::ifstream in(fixture_dir() / "000104.bin", std::ios::binary);
  float v[4];
  while (in && in.read(reinterpret_cast<char*>(v), sizeof v))
    if (v[0] != 0 || v[1] != 0 || v[2] != 0) pts.emplace_back(v[0], v[1], v[2]);
  return pts;
}

// The real scan when the fixture is there, else the synthetic one.
inline std::vector<Vec3f> benchmark_scan(bool* is_real = nullptr) {
  std::vector<Vec3f> pts = real_scan();
  if (is_real) *is_real = !pts.empty();
  return pts.empty() ? synthetic_scan() : pts;
}

// The RELLIS-3D camera (fixture camera_info.txt and published distortion) and its mounting.
inline CameraModel rellis_camera() {
  CameraModel c;
  c.width = 1920, c.height = 1200;
  c.fx = 2813.643275, c.fy = 2808.326079, c.cx = 969.285772, c.cy = 624.049972;
  c.distortion = {-0.134313, -0.025905, 0.002181, 0.00084, 0.0};
  return c;
}

inline Pose rellis_T_lidar_camera() {
  Pose T = Pose::Identity();
  T.linear() = Eigen::Quaterniond(-0.50507811, 0.51206185, 0.49024953, -0.49228464).normalized().toRotationMatrix();
  T.translation() = Vec3d(-0.13165462, 0.03870398, -0.17253834);
  return T;
}

}  // namespace slamvdb::bench
