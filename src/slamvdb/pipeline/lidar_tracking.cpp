#include "slamvdb/pipeline/lidar_tracking.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <numbers>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

std::size_t TrackingResult::registered() const {
  std::size_t failed = 0;
  for (const auto& [reason, n] : failures) failed += n;
  return stamps.size() - failed;
}

Pose TrackingResult::correction_at(double stamp) const {
  return loop_closer ? loop_closer->correction_at(stamp) : Pose::Identity();
}

Pose TrackingResult::corrected(std::size_t i) const { return correction_at(stamps.at(i)) * T_odom_sensor.at(i); }

namespace {
const TrackingOptions& validated(const TrackingOptions& options) {
  if (!std::isfinite(options.simulated_drift_deg_per_100m) || std::abs(options.simulated_drift_deg_per_100m) > 90)
    throw Error(fmt::format("simulated odometry drift {} degrees per 100 m: expected a finite value in [-90, 90]",
                            options.simulated_drift_deg_per_100m));
  options.odometry.validate();
  if (options.loop_closure) options.loops.validate();
  return options;
}
}  // namespace

LidarTracker::LidarTracker(const TrackingOptions& options) : options_(validated(options)), odometry_(options.odometry) {
  if (options.loop_closure) result_.loop_closer = std::make_unique<localization::LoopClosingMapper>(options.loops);
}

Pose LidarTracker::track(double stamp, const std::vector<Vec3f>& points, const std::vector<float>* point_times,
                         const std::string& name) {
  const auto start = std::chrono::steady_clock::now();
  localization::OdometryResult r = odometry_.register_scan(stamp, points, point_times);
  last_sweep_ = r.sweep;
  if (options_.simulated_drift_deg_per_100m != 0.0) {
    // The motion since the last scan, turned in proportion to its length, continues the drifted
    // trajectory (the odometry itself keeps tracking in its own frame).
    Pose motion = last_odometry_.inverse() * r.T_odom_sensor;
    last_odometry_ = r.T_odom_sensor;
    const double yaw = options_.simulated_drift_deg_per_100m * std::numbers::pi / 180.0 / 100.0 * motion.translation().norm();
    motion.linear() = motion.linear() * Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
    r.T_odom_sensor = result_.T_odom_sensor.empty() ? r.T_odom_sensor : result_.T_odom_sensor.back() * motion;
  }
  if (result_.loop_closer) result_.loop_closer->add_scan(stamp, r.T_odom_sensor, points, r.predicted_only);
  result_.busy_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result_.non_finite_points += r.non_finite_points;
  result_.out_of_range_points += r.out_of_range_points;
  result_.recovered += r.recovered && r.status == localization::ScanStatus::kOk;
  result_.empty_scans += points.empty();
  if (r.status != localization::ScanStatus::kOk) {
    ++result_.failures[to_string(r.status)];
    result_.problems.push_back(fmt::format("scan {} ({}): {}: {}; constant-velocity prediction used",
                                           result_.stamps.size(), name, to_string(r.status), r.reason));
    if (++consecutive_failures_ > options_.max_consecutive_failures)
      throw Error(fmt::format("odometry lost: {} scans in a row could not be registered (last: {})",
                              consecutive_failures_, name));
  } else {
    consecutive_failures_ = 0;
  }
  if (!result_.T_odom_sensor.empty())
    result_.distance += (r.T_odom_sensor.translation() - result_.T_odom_sensor.back().translation()).norm();
  result_.stamps.push_back(stamp);
  result_.T_odom_sensor.push_back(r.T_odom_sensor);
  return r.T_odom_sensor;
}

void LidarTracker::require_registered(const std::string& input, std::size_t unreadable) const {
  if (result_.registered() > 0) return;
  std::vector<std::string> reasons;
  if (unreadable) reasons.push_back(fmt::format("{} unreadable", unreadable));
  if (result_.empty_scans) reasons.push_back(fmt::format("{} empty", result_.empty_scans));
  for (const auto& [reason, n] : result_.failures) {
    const std::size_t count = reason == localization::to_string(localization::ScanStatus::kTooFewPoints)
                                  ? n - std::min(n, result_.empty_scans)
                                  : n;
    if (count) reasons.push_back(fmt::format("{} {}", count, reason));
  }
  const auto& o = options_.odometry;
  throw Error(fmt::format("{}: no scan could be registered ({} scans{}{}); a scan needs at least {} valid points "
                          "(finite, {} to {} m from the sensor)",
                          input, result_.stamps.size() + unreadable, reasons.empty() ? "" : ": ",
                          fmt::join(reasons, ", "), o.min_points, o.min_range, o.max_range));
}

TrackingResult track_scans(const std::vector<ScanFile>& scans, const TrackingOptions& options,
                           const TrackingProgress& progress) {
  LidarTracker tracker(options);
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const ScanPoints scan = load_scan_points(scans[i]);
    tracker.track(scans[i].stamp, scan.points, scan.time.empty() ? nullptr : &scan.time, scans[i].path.string());
    if (progress) progress(i + 1, scans.size(), tracker.result());
  }
  return tracker.take_result();
}

}  // namespace slamvdb
