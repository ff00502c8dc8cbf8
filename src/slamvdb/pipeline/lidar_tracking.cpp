#include "slamvdb/pipeline/lidar_tracking.hpp"

#include <fmt/format.h>

#include <chrono>

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

TrackingResult track_scans(const std::vector<ScanFile>& scans, const TrackingOptions& options,
                           const TrackingProgress& progress) {
  options.odometry.validate();
  if (options.loop_closure) options.loops.validate();
  localization::LidarOdometry odometry(options.odometry);
  TrackingResult result;
  if (options.loop_closure) result.loop_closer = std::make_unique<localization::LoopClosingMapper>(options.loops);
  int consecutive = 0;
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const ScanFile& file = scans[i];
    const ScanPoints scan = load_scan_points(file);
    const auto start = std::chrono::steady_clock::now();
    const localization::OdometryResult r =
        odometry.register_scan(file.stamp, scan.points, scan.time.empty() ? nullptr : &scan.time);
    if (result.loop_closer) result.loop_closer->add_scan(file.stamp, r.T_odom_sensor, scan.points, r.predicted_only);
    result.busy_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.non_finite_points += r.non_finite_points;
    result.out_of_range_points += r.out_of_range_points;
    result.recovered += r.recovered && r.status == localization::ScanStatus::kOk;
    if (r.status != localization::ScanStatus::kOk) {
      ++result.failures[to_string(r.status)];
      result.problems.push_back(fmt::format("scan {} ({}): {}: {}; constant-velocity prediction used", i,
                                            file.path.string(), to_string(r.status), r.reason));
      if (++consecutive > options.max_consecutive_failures)
        throw Error(fmt::format("odometry lost: {} scans in a row could not be registered (last: {})", consecutive,
                                file.path.string()));
    } else {
      consecutive = 0;
    }
    if (!result.T_odom_sensor.empty())
      result.distance += (r.T_odom_sensor.translation() - result.T_odom_sensor.back().translation()).norm();
    result.stamps.push_back(file.stamp);
    result.T_odom_sensor.push_back(r.T_odom_sensor);
    if (progress) progress(i + 1, scans.size(), result);
  }
  return result;
}

}  // namespace slamvdb
