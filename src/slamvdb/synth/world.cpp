#include "slamvdb/synth/world.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/synth/camera_sim.hpp"
#include "slamvdb/synth/random.hpp"
#include "slamvdb/synth/scene_layout.hpp"

namespace slamvdb::synth {

void SynthConfig::validate() const {
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("invalid synthetic sequence setting: " + what);
  };
  require(std::isfinite(length_m) && length_m > 0.0, fmt::format("length {} m must be > 0", length_m));
  require(std::isfinite(speed_mps) && speed_mps > 0.0 && speed_mps <= 40.0,
          fmt::format("speed {} m/s must be in (0, 40]", speed_mps));
  require(revisit_overlap_m >= 0.0, fmt::format("revisit overlap {} m must be >= 0", revisit_overlap_m));
  require(min_loop_m >= 60.0, fmt::format("minimum loop {} m must be >= 60 m", min_loop_m));
  require(sensor_height_m >= 0.3 && sensor_height_m <= 5.0,
          fmt::format("sensor height {} m must be in [0.3, 5]", sensor_height_m));
  require(lidar_rate_hz > 0.0 && lidar_rate_hz <= 100.0,
          fmt::format("LiDAR rate {} Hz must be in (0, 100]", lidar_rate_hz));
  require(camera_rate_hz > 0.0 && camera_rate_hz <= 100.0,
          fmt::format("camera rate {} Hz must be in (0, 100]", camera_rate_hz));
  require(camera_jitter_s >= 0.0 && camera_jitter_s < 0.25 / camera_rate_hz,
          fmt::format("camera jitter {} s must be >= 0 and under a quarter of the camera period", camera_jitter_s));
  require(camera_offset_s >= 0.0, fmt::format("camera offset {} s must be >= 0", camera_offset_s));
  require(camera_max_range_m > 0.0, fmt::format("camera range {} m must be > 0", camera_max_range_m));
  require(image_width >= 16 && image_height >= 16 && image_width <= 8192 && image_height <= 8192,
          fmt::format("image size {}x{} must be within 16..8192 pixels per side", image_width, image_height));
  require(jpeg_quality >= 1 && jpeg_quality <= 100, fmt::format("JPEG quality {} must be in 1..100", jpeg_quality));
  require(std::isfinite(base_stamp) && base_stamp >= 0.0, fmt::format("base stamp {} must be >= 0", base_stamp));
  require(std::isfinite(rig_translation_error_m) && rig_translation_error_m >= 0.0 && rig_translation_error_m <= 1.0,
          fmt::format("rig translation error {} m must be in [0, 1]", rig_translation_error_m));
  require(std::isfinite(rig_rotation_error_deg) && rig_rotation_error_deg >= 0.0 && rig_rotation_error_deg <= 10.0,
          fmt::format("rig rotation error {} deg must be in [0, 10]", rig_rotation_error_deg));
  require(std::isfinite(rig_time_offset_s) && std::abs(rig_time_offset_s) <= 0.1,
          fmt::format("rig time offset {} s must be within +-0.1 s", rig_time_offset_s));
  require(std::isfinite(loop_length_m) && (loop_length_m == 0.0 || loop_length_m >= 60.0),
          fmt::format("loop length {} m must be 0 (from the length) or >= 60 m", loop_length_m));
  require(std::isfinite(start_offset_m) && start_offset_m >= 0.0,
          fmt::format("start offset {} m must be >= 0", start_offset_m));
  require(repeat_spacing_m >= 10.0, fmt::format("repeat spacing {} m must be >= 10", repeat_spacing_m));
  require(std::isfinite(lidar_sweep_s) && lidar_sweep_s >= 0.0 && lidar_sweep_s <= 1.0 / lidar_rate_hz,
          fmt::format("LiDAR sweep {} s must be in [0, the scan period {} s]", lidar_sweep_s, 1.0 / lidar_rate_hz));
  lidar.validate();
}

namespace {

// The nominal extrinsic moved by the configured errors: a translation of the given length and a
// rotation by the given angle, about and along directions drawn from the seed.
Pose true_T_lidar_camera(const Pose& nominal, const SynthConfig& config) {
  Rng rng(config.sensor_seed(), Stream::kRigError, 0);
  const auto direction = [&] {
    Vec3d d;
    do d = Vec3d(rng.gaussian(), rng.gaussian(), rng.gaussian());
    while (d.norm() < 1e-6);
    return Vec3d(d.normalized());
  };
  const Vec3d t = direction() * config.rig_translation_error_m;
  const Vec3d axis = direction();
  Pose error = Pose::Identity();
  error.linear() = Eigen::AngleAxisd(config.rig_rotation_error_deg * M_PI / 180.0, axis).toRotationMatrix();
  error.translation() = t;
  return nominal * error;  // the error in the camera's own frame
}

}  // namespace

double SynthConfig::loop_perimeter() const {
  return loop_length_m > 0.0 ? loop_length_m : std::max(length_m - revisit_overlap_m, min_loop_m);
}

SynthWorld build_synthetic_world(const SynthConfig& config) {
  config.validate();
  LoopPath path(config.loop_perimeter(), config.seed);
  auto scene = std::make_shared<const Scene>(config.scene == SceneKind::kRepeatedPlaces
                                                 ? build_repeated_places_scene(path, config.seed, config.repeat_spacing_m)
                                                 : build_offroad_scene(path, config.seed));
  std::shared_ptr<const Terrain> terrain(scene, &scene->terrain());
  SimulatedTrajectory trajectory(std::move(path), terrain, config.speed_mps, config.sensor_height_m,
                                 config.start_offset_m, config.reverse);
  SynthWorld world{config,
                   scene,
                   std::move(trajectory),
                   rellis_camera(config.image_width, config.image_height),
                   rellis_T_lidar_camera(),
                   true_T_lidar_camera(rellis_T_lidar_camera(), config),
                   {},
                   {},
                   {},
                   0.0};

  // Scans until the driven length reaches the request.
  const double scan_period = 1.0 / config.lidar_rate_hz;
  for (std::size_t i = 0; world.scan_stamps.empty() || world.path_length_m < config.length_m; ++i) {
    const double elapsed = static_cast<double>(i) * scan_period;
    const Pose pose = world.trajectory.T_world_lidar(elapsed);
    if (!world.scan_poses.empty())
      world.path_length_m += (pose.translation() - world.scan_poses.back().translation()).norm();
    world.scan_stamps.push_back(config.base_stamp + elapsed);
    world.scan_poses.push_back(pose);
  }
  // Camera frames at their own rate, offset and jittered, on whole milliseconds (the file names'
  // resolution), never on a scan stamp, always within the scans' time span.
  const double first = world.scan_stamps.front(), last = world.scan_stamps.back();
  for (std::size_t k = 0;; ++k) {
    Rng rng(config.sensor_seed(), Stream::kCameraJitter, k);
    const double stamp = first + config.camera_offset_s + static_cast<double>(k) / config.camera_rate_hz +
                         rng.uniform(-config.camera_jitter_s, config.camera_jitter_s);
    int64_t ms = std::llround(stamp * 1000.0);
    const double nearest_scan = first + std::round((ms / 1000.0 - first) / scan_period) * scan_period;
    if (std::abs(ms / 1000.0 - nearest_scan) < 0.0005) ++ms;
    if (ms / 1000.0 > last) break;
    if (ms / 1000.0 < first) continue;
    world.camera_stamps_ms.push_back(ms);
  }
  return world;
}

}  // namespace slamvdb::synth
