#pragma once
// Everything a simulated sequence is made from, in memory: the scene, the ground-truth drive, the
// sensor models and every scan and camera time stamp. The writer turns it into files; tests and
// the pipeline can use it directly.
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/synth/lidar_sim.hpp"
#include "slamvdb/synth/scene.hpp"
#include "slamvdb/synth/trajectory_sim.hpp"

namespace slamvdb::synth {

// kOffroad: the default loop trail scene. kRepeatedPlaces: the same arrangement of objects (a shed,
// a parked vehicle, trees, a pole, barriers) repeated every `repeat_spacing_m` along the trail on
// otherwise bare grass, for testing that place recognition does not close false loops.
enum class SceneKind { kOffroad, kRepeatedPlaces };

struct SynthConfig {
  uint64_t seed = 1;
  SceneKind scene = SceneKind::kOffroad;
  double repeat_spacing_m = 30.0;  // kRepeatedPlaces only
  double length_m = 320.0;  // driven path length (at least)
  double speed_mps = 5.0;
  double revisit_overlap_m = 25.0;  // the loop closes after length - overlap; the drive goes on past its start
  double min_loop_m = 120.0;        // shortest loop built, so short test drives still see a full scene
  // Several drives over one scene (issue 23): `seed` fixes the scene and the loop's shape; these
  // place a drive on the loop. All at their defaults, a sequence is what it was before them.
  double loop_length_m = 0.0;   // the loop's perimeter; 0: max(length - revisit overlap, min loop)
  double start_offset_m = 0.0;  // arc length along the loop where the drive starts
  bool reverse = false;         // drive the loop clockwise (the trail and the scene unchanged)
  // The LiDAR noise, the camera jitter and the rig errors; unset: `seed` (the scene's).
  std::optional<uint64_t> noise_seed;
  uint64_t sensor_seed() const { return noise_seed.value_or(seed); }
  double loop_perimeter() const;
  double sensor_height_m = 1.5;
  double lidar_rate_hz = 10.0;
  double camera_rate_hz = 5.0;
  double camera_offset_s = 0.037;  // first image after the first scan; images are not aligned to scans
  double camera_jitter_s = 0.002;  // uniform +- jitter per image
  double camera_max_range_m = 200.0;
  int image_width = 640, image_height = 400;
  int jpeg_quality = 90;
  bool keep_no_return = false;  // write no-return rays as all-zero points (label 0) like the real sensor
  // SIMULATED rotating sweep (lidar_sim.hpp simulate_swept_scan), seconds; 0: each scan is cast
  // from the pose at its stamp. When > 0 (e.g. 0.1 at 10 Hz) each column is cast from the pose at
  // its own time after the stamp, and the per-point times are written (kPointTimesDir).
  double lidar_sweep_s = 0.0;
  double base_stamp = 1700000000.0;
  // The rig's own SIMULATED errors, on by default: a real camera-LiDAR calibration is off by a few
  // centimetres and tenths of a degree, and a camera's time stamp by a few milliseconds. The images
  // are rendered from the TRUE camera (the written extrinsic moved by these errors, in a direction
  // drawn from the seed) at the TRUE capture time (the stamp plus the offset), while
  // transforms.yaml and the file names carry the nominal values, so a map made from the sequence
  // lives with the errors as with a real rig. synth.json records them. All zero: a perfect rig.
  double rig_translation_error_m = 0.03;
  double rig_rotation_error_deg = 0.3;
  double rig_time_offset_s = 0.005;
  // Write pylon_camera_node_sim_view/ (camera_sim.hpp): the SIMULATED per-pixel view geometry the
  // simulated encoder's view-dependent and persistent errors are keyed to.
  bool view_geometry = true;
  LidarModel lidar;

  void validate() const;  // throws Error naming the bad parameter
};

struct SynthWorld {
  SynthConfig config;
  std::shared_ptr<const Scene> scene;
  SimulatedTrajectory trajectory;
  CameraModel camera;  // at the written image size
  Pose T_lidar_camera = Pose::Identity();       // nominal: what transforms.yaml says
  Pose T_lidar_camera_true = Pose::Identity();  // what the images are rendered with (rig errors)
  std::vector<double> scan_stamps;        // absolute seconds, LiDAR rate
  std::vector<Pose> scan_poses;           // ground truth T_world_lidar at scan_stamps
  std::vector<int64_t> camera_stamps_ms;  // absolute milliseconds (the file names' resolution)
  double path_length_m = 0.0;             // along the scan positions

  // Ground truth at any time within the drive (continuous, not interpolated between scans).
  Pose T_world_lidar(double stamp) const { return trajectory.T_world_lidar(stamp - config.base_stamp); }
  Pose T_world_camera(double stamp) const { return T_world_lidar(stamp) * T_lidar_camera; }
  // Where the camera really was for the image stamped `stamp` (rig errors included).
  Pose T_world_camera_true(double stamp) const {
    return T_world_lidar(stamp + config.rig_time_offset_s) * T_lidar_camera_true;
  }
};

SynthWorld build_synthetic_world(const SynthConfig& config);

}  // namespace slamvdb::synth
