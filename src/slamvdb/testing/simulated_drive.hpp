#pragma once
// For tests only: a SIMULATED drive (synth world + simulated OS1-64 scans) held in memory, so
// localization tests need no files. It lives with the other fixtures, not in localization/, which
// knows nothing of the simulator.
#include <tbb/parallel_for.h>

#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/synth/world.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb::testing {

struct SimulatedDrive {
  synth::SynthWorld world;
  std::vector<double> stamps;
  std::vector<Pose> T_world_sensor;  // ground truth
  std::vector<std::vector<Vec3f>> scans;
  double path_length_m = 0.0;
};

// Scans `first` .. first + count - 1 (all if count is 0) of the world built from `config`.
inline SimulatedDrive simulate_drive(const synth::SynthConfig& config, std::size_t first = 0, std::size_t count = 0) {
  SimulatedDrive drive{synth::build_synthetic_world(config), {}, {}, {}, 0.0};
  const auto& w = drive.world;
  const std::size_t end = count == 0 ? w.scan_stamps.size() : std::min(w.scan_stamps.size(), first + count);
  for (std::size_t i = first; i < end; ++i) {
    drive.stamps.push_back(w.scan_stamps[i]);
    drive.T_world_sensor.push_back(w.scan_poses[i]);
    if (i > first) drive.path_length_m += (w.scan_poses[i].translation() - w.scan_poses[i - 1].translation()).norm();
  }
  drive.scans.resize(drive.stamps.size());
  const std::vector<Vec3d> rays = config.lidar.ray_directions();
  tbb::parallel_for(std::size_t{0}, drive.scans.size(), [&](std::size_t k) {
    const synth::SimulatedScan s =
        synth::simulate_scan(*w.scene, config.lidar, rays, drive.T_world_sensor[k], config.sensor_seed(), first + k, false);
    drive.scans[k].reserve(s.points.size());
    for (const auto& p : s.points) drive.scans[k].push_back(p.head<3>());
  });
  return drive;
}

}  // namespace slamvdb::testing
