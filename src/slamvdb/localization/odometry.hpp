#pragma once
// LiDAR odometry in the spirit of KISS-ICP (Vizzo et al., "KISS-ICP: In Defense of Point-to-Point
// ICP", RA-L 2023), written from the paper: constant-velocity prediction, optional deskewing,
// two-level voxel downsampling, a voxel-hash local map kept within the sensor range, and robust
// point-to-point ICP whose correspondence threshold adapts to the observed prediction error.
//
// A scan that cannot be registered is never given a silently wrong pose: its result carries a
// status other than kOk, `predicted_only` is set and the pose is the constant-velocity prediction
// (the local map is not updated from it). Callers count these and decide (the CLI fails after
// too many in a row).
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/localization/preprocessing.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"

namespace slamvdb::localization {

struct OdometryConfig {
  double max_range = 100.0;  // metres; farther returns are dropped
  double min_range = 1.0;    // closer returns (the vehicle itself, no-return zeros) are dropped
  double voxel_size = 1.0;   // local-map voxel edge; the scan is kept at half of it, ICP uses 1.5x
  int max_points_per_voxel = 20;
  double initial_threshold = 2.0;  // metres, correspondence threshold before any motion was seen
  double min_motion = 0.1;         // deviations below this do not update the adaptive threshold
  bool deskew = true;              // when per-point times are given
  int max_iterations = 500;
  double convergence = 1e-4;
  std::size_t min_points = 100;         // fewer valid points: the scan is skipped
  double inlier_distance = 0.5;         // metres, for the alignment check
  double min_inlier_fraction = 0.5;     // of the ICP points after alignment; below: retried, then failed
  double recovery_threshold = 6.0;      // metres: widest correspondence threshold when retrying
  void validate() const;                // throws Error naming the bad setting
};

enum class ScanStatus {
  kOk,                  // registered (or the first scan, which defines the odometry frame)
  kTooFewPoints,        // fewer than min_points valid points after dropping NaN / out-of-range ones
  kRegistrationFailed,  // ICP found too few correspondences or an alignment below min_inlier_fraction
};
const char* to_string(ScanStatus status);

struct OdometryResult {
  Pose T_odom_sensor = Pose::Identity();
  ScanStatus status = ScanStatus::kOk;
  bool predicted_only = false;  // the pose is the constant-velocity prediction, not a registration
  bool recovered = false;       // registered only after retrying with a wide threshold
  std::string reason;           // why the scan was not registered, for logs
  std::size_t input_points = 0, valid_points = 0, registration_points = 0;
  std::size_t non_finite_points = 0, out_of_range_points = 0;
  int iterations = 0;
  double threshold = 0.0;        // correspondence threshold used (metres)
  double inlier_fraction = 0.0;  // after alignment
  // When the scan was deskewed: the motion it was deskewed with (the pose refers to mid-sweep), so
  // that the mapper can fuse the whole scan deskewed the same way.
  std::optional<SweepMotion> sweep;
};

class LidarOdometry {
 public:
  explicit LidarOdometry(OdometryConfig config = {});

  // Registers one scan (sensor frame) taken at `stamp` (seconds, strictly increasing: throws
  // Error otherwise). `point_times` (same length as the points, any unit/offset) enables
  // deskewing. Returns T_odom_sensor: the odometry frame is the sensor frame of the first scan.
  OdometryResult register_scan(double stamp, const std::vector<Vec3f>& points_sensor,
                               const std::vector<float>* point_times = nullptr);

  const VoxelHashMap& local_map() const { return map_; }
  double adaptive_threshold() const;
  const OdometryConfig& config() const { return config_; }

 private:
  Pose predict(double stamp) const;
  void update_threshold(const Pose& model_deviation);
  void accept(double stamp, const Pose& T_odom_sensor);

  OdometryConfig config_;
  VoxelHashMap map_;
  std::optional<double> last_stamp_, previous_stamp_;
  Pose last_pose_ = Pose::Identity(), previous_pose_ = Pose::Identity();
  double model_sse_ = 0.0;
  std::size_t model_samples_ = 0;
};

}  // namespace slamvdb::localization
