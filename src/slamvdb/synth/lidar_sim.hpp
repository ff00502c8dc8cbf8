#pragma once
// A simulated Ouster OS1-64-like spinning LiDAR: 64 evenly spaced beams over +-16.6 degrees,
// 1024 columns per turn, Gaussian range noise. A scan is taken from one pose (no motion distortion
// within the sweep), or SIMULATED as swept (simulate_swept_scan): each column at its own time, from
// the pose at that time, as a real spinning LiDAR takes it while the vehicle moves.
#include <cstdint>
#include <functional>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/synth/scene.hpp"

namespace slamvdb::synth {

struct LidarModel {
  int beams = 64;
  int columns = 1024;
  double fov_up_deg = 16.6, fov_down_deg = -16.6;
  double min_range = 0.8, max_range = 100.0;
  double range_noise_sigma = 0.02;  // metres

  void validate() const;             // throws Error on a nonsensical model
  double elevation(int beam) const;  // radians; beam 0 is the top one
  double azimuth(int column) const;  // radians; columns turn clockwise from +x, as the Ouster does
  // Unit ray directions in the LiDAR frame, column-major like RELLIS-3D's OS1 files:
  // ray index = column * beams + beam.
  std::vector<Vec3d> ray_directions() const;
};

struct SimulatedScan {
  std::vector<Eigen::Vector4f> points;  // x y z intensity, LiDAR frame; intensity on RELLIS's scale (~0..0.012)
  std::vector<uint16_t> labels;         // RELLIS-3D class per point (0 for a kept no-return)
  std::vector<uint32_t> ray_index;      // the ray of ray_directions() each point came from
  std::size_t no_returns = 0;           // rays without a return, whether kept as zeros or dropped
  std::vector<float> times;             // swept scans: seconds since the scan's stamp per point; else empty
};

// Relative LiDAR reflectivity of a class (retro-reflective barriers bright, water dark).
double lidar_reflectivity(uint16_t label);

// Casts every ray from T_world_lidar. Noise comes from the stream (seed, scan_index), so a scan
// is reproducible on its own, in any order and on any thread. No-return rays are counted and, if
// keep_no_return, written as all-zero points (as the real sensor's files do).
SimulatedScan simulate_scan(const Scene& scene, const LidarModel& model, const std::vector<Vec3d>& rays,
                            const Pose& T_world_lidar, uint64_t seed, uint64_t scan_index, bool keep_no_return);

// The same, SIMULATED as swept over `sweep_seconds` (a rotating LiDAR: 0.1 s at 10 Hz): column c
// is cast at time sweep_seconds * c / columns after the scan's stamp, from T_world_lidar_at(that
// time) (times relative to the stamp), and every point gets its column's time in `times`, as a
// real driver's per-point time field (Ouster's `t`) gives it. Points stay in the LiDAR frame of
// their own column's pose. The same noise as simulate_scan, so zero motion gives the same points.
SimulatedScan simulate_swept_scan(const Scene& scene, const LidarModel& model, const std::vector<Vec3d>& rays,
                                  const std::function<Pose(double)>& T_world_lidar_at, double sweep_seconds,
                                  uint64_t seed, uint64_t scan_index, bool keep_no_return);

}  // namespace slamvdb::synth
