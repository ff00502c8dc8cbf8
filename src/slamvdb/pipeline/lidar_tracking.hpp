#pragma once
// The project's own poses: LiDAR odometry over a list of scan files, optionally with the
// loop-closing mapper, as `slamvdb odometry` and `slamvdb slam` run it. Scan-level failures are
// counted by reason (the constant-velocity prediction stands in), too many in a row is an Error.
#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/io/scan_source.hpp"
#include "slamvdb/localization/loop_closure.hpp"
#include "slamvdb/localization/odometry.hpp"

namespace slamvdb {

struct TrackingOptions {
  localization::OdometryConfig odometry;
  bool loop_closure = true;
  localization::LoopClosureConfig loops;
  int max_consecutive_failures = 10;
  // SIMULATED odometry drift, degrees of heading error per 100 m travelled (0: none): each
  // registered motion is turned by this much about the sensor's z axis before the loop closer and
  // the mapper see it, as a biased gyro would. For exercising loop closure on simulated drives,
  // whose odometry drifts only centimetres.
  double simulated_drift_deg_per_100m = 0.0;
};

struct TrackingResult {
  std::vector<double> stamps;
  std::vector<Pose> T_odom_sensor;  // odometry, frame of the first scan
  std::map<std::string, std::size_t> failures;  // scans not registered, by reason
  std::vector<std::string> problems;            // one line per such scan
  std::size_t non_finite_points = 0, out_of_range_points = 0, recovered = 0;
  std::size_t empty_scans = 0;  // scans without a single point (among those with too few valid points)
  double distance = 0.0;        // odometry path length (m)
  double busy_seconds = 0.0;    // registration and loop closure, not file reading
  std::unique_ptr<localization::LoopClosingMapper> loop_closer;  // when options.loop_closure

  std::size_t registered() const;
  // The corrected pose of scan i (T_world_sensor with world = odom corrected by the loops), or the
  // odometry pose without loop closure.
  Pose corrected(std::size_t i) const;
  // T_world_odom at a stamp (identity without loop closure).
  Pose correction_at(double stamp) const;
};

// Tracks scans one at a time as they arrive (what `track_scans` and the streaming `slam` run on).
class LidarTracker {
 public:
  explicit LidarTracker(const TrackingOptions& options);  // throws Error for invalid options
  // Registers the next scan (stamps increasing) and returns its odometry pose T_odom_sensor; a
  // scan that cannot be registered gets the constant-velocity prediction and is counted. Throws
  // Error when more than max_consecutive_failures scans in a row fail.
  Pose track(double stamp, const std::vector<Vec3f>& points, const std::vector<float>* point_times,
             const std::string& name);
  // Throws Error naming `input` when not one scan could be registered (the first one with enough
  // points, which defines the odometry frame, counts): every pose would be a guess. The message
  // gives the scans by reason (empty, too few valid points, registration failed, and the
  // `unreadable` ones the caller could not load) and what a scan needs.
  void require_registered(const std::string& input, std::size_t unreadable = 0) const;
  // The motion the last scan was deskewed with (its pose refers to mid-sweep), or nullopt when it
  // was not (no per-point times, deskewing off, or no motion seen yet: the first two scans).
  const std::optional<localization::SweepMotion>& last_sweep() const { return last_sweep_; }
  const TrackingResult& result() const { return result_; }
  TrackingResult take_result() { return std::move(result_); }

 private:
  TrackingOptions options_;
  localization::LidarOdometry odometry_;
  TrackingResult result_;
  Pose last_odometry_ = Pose::Identity();  // the odometry's own last pose (before simulated drift)
  int consecutive_failures_ = 0;
  std::optional<localization::SweepMotion> last_sweep_;
};

// progress(done, total, result so far) after every scan.
using TrackingProgress = std::function<void(std::size_t, std::size_t, const TrackingResult&)>;
TrackingResult track_scans(const std::vector<ScanFile>& scans, const TrackingOptions& options,
                           const TrackingProgress& progress = {});

}  // namespace slamvdb
