#include "slamvdb/synth/lidar_sim.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "slamvdb/core/error.hpp"
#include "slamvdb/synth/random.hpp"

namespace slamvdb::synth {

namespace {
constexpr double kDegToRad = std::numbers::pi / 180.0;
// RELLIS-3D stores the OS1's 16-bit intensity divided by 65535; a bright return reaches ~0.012.
constexpr double kIntensityScale = 0.012;
}  // namespace

void LidarModel::validate() const {
  if (beams < 1 || columns < 1)
    throw Error(fmt::format("simulated LiDAR needs at least one beam and column (got {} x {})", beams, columns));
  if (!(fov_up_deg > fov_down_deg) || fov_up_deg > 90.0 || fov_down_deg < -90.0)
    throw Error(
        fmt::format("simulated LiDAR vertical field [{}, {}] deg is not a valid interval", fov_down_deg, fov_up_deg));
  if (!(min_range >= 0.0) || !(max_range > min_range))
    throw Error(fmt::format("simulated LiDAR range [{}, {}] m is not a valid interval", min_range, max_range));
  if (!(range_noise_sigma >= 0.0))
    throw Error(fmt::format("simulated LiDAR range noise {} m must be >= 0", range_noise_sigma));
}

double LidarModel::elevation(int beam) const {
  const double f = beams > 1 ? static_cast<double>(beam) / (beams - 1) : 0.5;
  return (fov_up_deg + f * (fov_down_deg - fov_up_deg)) * kDegToRad;
}

double LidarModel::azimuth(int column) const { return -2.0 * std::numbers::pi * column / columns; }

std::vector<Vec3d> LidarModel::ray_directions() const {
  std::vector<Vec3d> rays;
  rays.reserve(static_cast<std::size_t>(beams) * columns);
  for (int c = 0; c < columns; ++c) {
    const double az = azimuth(c);
    for (int b = 0; b < beams; ++b) {
      const double el = elevation(b);
      rays.emplace_back(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
    }
  }
  return rays;
}

double lidar_reflectivity(uint16_t label) {
  switch (label) {
    case 1:
      return 0.35;  // dirt
    case 3:
      return 0.45;  // grass
    case 4:
      return 0.5;  // tree
    case 5:
      return 0.4;  // pole
    case 8:
      return 0.7;  // vehicle
    case 10:
      return 0.15;  // asphalt
    case 12:
      return 0.4;  // building
    case 15:
      return 0.35;  // log
    case 17:
      return 0.3;  // person
    case 18:
      return 0.45;  // fence
    case 19:
      return 0.5;  // bush
    case 23:
      return 0.35;  // concrete
    case 27:
      return 0.9;  // barrier (retro-reflective strips)
    case 31:
      return 0.05;  // puddle
    case 33:
      return 0.2;  // mud
    case 34:
      return 0.3;  // rubble
    default:
      return 0.3;
  }
}

namespace {

// Casts every ray from the pose of its column (ray = column * beams + beam); with `times`, each
// point gets its column's time.
SimulatedScan cast_scan(const Scene& scene, const LidarModel& model, const std::vector<Vec3d>& rays,
                        const std::vector<Pose>& T_world_lidar_per_column, const std::vector<float>* column_times,
                        uint64_t seed, uint64_t scan_index, bool keep_no_return) {
  SimulatedScan scan;
  scan.points.reserve(rays.size());
  scan.labels.reserve(rays.size());
  scan.ray_index.reserve(rays.size());
  if (column_times) scan.times.reserve(rays.size());
  Rng rng(seed, Stream::kLidarNoise, scan_index);
  const std::size_t beams = static_cast<std::size_t>(model.beams);
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const std::size_t column = std::min(i / beams, T_world_lidar_per_column.size() - 1);
    const Pose& T_world_lidar = T_world_lidar_per_column[column];
    // Draw the noise for every ray, hit or not, so one ray's outcome never shifts another's.
    const double noise = model.range_noise_sigma * rng.gaussian();
    const double speckle = rng.uniform(0.9, 1.1);
    const Vec3d dir = T_world_lidar.linear() * rays[i];
    const auto hit = scene.raycast(T_world_lidar.translation(), dir, model.max_range);
    const double range = hit ? hit->range + noise : 0.0;
    if (!hit || range < model.min_range || range > model.max_range) {
      ++scan.no_returns;
      if (!keep_no_return) continue;
      scan.points.emplace_back(Eigen::Vector4f::Zero());
      scan.labels.push_back(0);
    } else {
      const double incidence = std::abs(hit->normal.dot(dir));
      const double intensity = kIntensityScale * lidar_reflectivity(hit->label) * (0.25 + 0.75 * incidence) * speckle;
      const Vec3d p = range * rays[i];
      scan.points.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()),
                               static_cast<float>(intensity));
      scan.labels.push_back(hit->label);
    }
    scan.ray_index.push_back(static_cast<uint32_t>(i));
    if (column_times) scan.times.push_back((*column_times)[column]);
  }
  return scan;
}

}  // namespace

SimulatedScan simulate_scan(const Scene& scene, const LidarModel& model, const std::vector<Vec3d>& rays,
                            const Pose& T_world_lidar, uint64_t seed, uint64_t scan_index, bool keep_no_return) {
  return cast_scan(scene, model, rays, {T_world_lidar}, nullptr, seed, scan_index, keep_no_return);
}

SimulatedScan simulate_swept_scan(const Scene& scene, const LidarModel& model, const std::vector<Vec3d>& rays,
                                  const std::function<Pose(double)>& T_world_lidar_at, double sweep_seconds,
                                  uint64_t seed, uint64_t scan_index, bool keep_no_return) {
  if (!(sweep_seconds >= 0.0) || !std::isfinite(sweep_seconds))
    throw Error(fmt::format("simulated LiDAR sweep {} s must be finite and >= 0", sweep_seconds));
  std::vector<Pose> poses(static_cast<std::size_t>(model.columns));
  std::vector<float> times(poses.size());
  for (std::size_t c = 0; c < poses.size(); ++c) {
    const double t = sweep_seconds * static_cast<double>(c) / model.columns;
    times[c] = static_cast<float>(t);
    poses[c] = T_world_lidar_at(t);
  }
  return cast_scan(scene, model, rays, poses, &times, seed, scan_index, keep_no_return);
}

}  // namespace slamvdb::synth
