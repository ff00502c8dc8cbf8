#include "slamvdb/localization/odometry.hpp"

#include <fmt/format.h>

#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/se3.hpp"
#include "slamvdb/localization/preprocessing.hpp"
#include "slamvdb/localization/registration.hpp"

namespace slamvdb::localization {

void OdometryConfig::validate() const {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("invalid odometry setting: " + what);
  };
  require(max_range > 0.0 && std::isfinite(max_range), fmt::format("max range {} must be > 0", max_range));
  require(min_range >= 0.0 && min_range < max_range, fmt::format("min range {} must be in [0, max range)", min_range));
  require(voxel_size > 0.0 && voxel_size < max_range, fmt::format("voxel size {} must be > 0", voxel_size));
  require(max_points_per_voxel >= 1, "max points per voxel must be >= 1");
  require(initial_threshold > 0.0, fmt::format("initial threshold {} must be > 0", initial_threshold));
  require(max_iterations >= 1, "max iterations must be >= 1");
  require(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0, "min inlier fraction must be in [0, 1]");
  require(inlier_distance > 0.0, "inlier distance must be > 0");
  require(min_points >= 10, "min points must be >= 10");
}

const char* to_string(ScanStatus status) {
  switch (status) {
    case ScanStatus::kOk: return "ok";
    case ScanStatus::kTooFewPoints: return "too few valid points";
    case ScanStatus::kRegistrationFailed: return "registration failed";
  }
  return "?";
}

LidarOdometry::LidarOdometry(OdometryConfig config)
    : config_((config.validate(), config)),
      map_(config.voxel_size, config.max_range, config.max_points_per_voxel) {}

double LidarOdometry::adaptive_threshold() const {
  if (model_samples_ == 0) return config_.initial_threshold;
  return std::sqrt(model_sse_ / static_cast<double>(model_samples_));
}

void LidarOdometry::update_threshold(const Pose& model_deviation) {
  // KISS-ICP's bound on how far a point at max range moves under the deviation.
  const double theta = Eigen::AngleAxisd(model_deviation.linear()).angle();
  const double error = 2.0 * config_.max_range * std::sin(0.5 * theta) + model_deviation.translation().norm();
  if (error > config_.min_motion) {
    model_sse_ += error * error;
    ++model_samples_;
  }
}

Pose LidarOdometry::predict(double stamp) const {
  if (!last_stamp_) return Pose::Identity();
  if (!previous_stamp_) return last_pose_;
  // Constant velocity in time, so a gap (dropped scans) is bridged by a proportionally longer step.
  const double scale = (stamp - *last_stamp_) / (*last_stamp_ - *previous_stamp_);
  return last_pose_ * se3_exp(scale * se3_log(previous_pose_.inverse() * last_pose_));
}

void LidarOdometry::accept(double stamp, const Pose& T_odom_sensor) {
  previous_stamp_ = last_stamp_;
  previous_pose_ = last_pose_;
  last_stamp_ = stamp;
  last_pose_ = T_odom_sensor;
}

OdometryResult LidarOdometry::register_scan(double stamp, const std::vector<Vec3f>& points_sensor,
                                            const std::vector<float>* point_times) {
  if (!std::isfinite(stamp)) throw Error("odometry: scan stamp is not finite");
  if (last_stamp_ && !(stamp > *last_stamp_))
    throw Error(fmt::format("odometry: scan stamps must increase, but {:.6f} follows {:.6f}", stamp, *last_stamp_));
  if (point_times && point_times->size() != points_sensor.size())
    throw Error(fmt::format("odometry: {} point times for {} points", point_times->size(), points_sensor.size()));

  OdometryResult result;
  result.input_points = points_sensor.size();
  PointFilterStats stats;
  std::vector<double> times;
  std::vector<Vec3d> points = filter_points(points_sensor, config_.min_range, config_.max_range, stats, point_times,
                                            point_times ? &times : nullptr);
  result.valid_points = stats.kept();
  result.non_finite_points = stats.non_finite;
  result.out_of_range_points = stats.out_of_range;
  const Pose prediction = predict(stamp);
  const auto fail = [&](ScanStatus status, std::string reason) {
    result.status = status;
    result.reason = std::move(reason);
    result.predicted_only = true;
    result.T_odom_sensor = prediction;
    if (last_stamp_) accept(stamp, prediction);
    else accept(stamp, Pose::Identity());
    return result;
  };
  if (points.size() < config_.min_points)
    return fail(ScanStatus::kTooFewPoints,
                fmt::format("{} valid points of {} ({} non-finite, {} out of [{}, {}] m), fewer than {}",
                            points.size(), points_sensor.size(), stats.non_finite, stats.out_of_range,
                            config_.min_range, config_.max_range, config_.min_points));

  if (point_times && config_.deskew && previous_stamp_) {
    result.sweep = sweep_motion(times, previous_pose_.inverse() * last_pose_);
    points = deskew(points, times, *result.sweep);
  }
  const std::vector<Vec3d> frame = voxel_downsample(points, 0.5 * config_.voxel_size);
  const std::vector<Vec3d> source = voxel_downsample(frame, 1.5 * config_.voxel_size);
  result.registration_points = source.size();

  if (map_.empty()) {  // the first scan defines the odometry frame
    result.T_odom_sensor = Pose::Identity();
    map_.update(frame, result.T_odom_sensor);
    accept(stamp, result.T_odom_sensor);
    result.inlier_fraction = 1.0;
    return result;
  }

  const auto register_with = [&](double threshold) {
    IcpOptions icp;
    icp.max_correspondence_distance = 3.0 * threshold;
    icp.kernel_scale = threshold / 3.0;
    icp.max_iterations = config_.max_iterations;
    icp.convergence = config_.convergence;
    return align_point_to_point(source, map_, prediction, icp);
  };
  const double sigma = adaptive_threshold();
  result.threshold = sigma;
  IcpResult icp = register_with(sigma);
  AlignmentQuality quality = alignment_quality(source, map_, icp.T_target_source, config_.inlier_distance);
  if (!icp.enough_correspondences || quality.inlier_fraction() < config_.min_inlier_fraction) {
    // Retry from the prediction with a wide threshold (a jump the motion model did not foresee),
    // then tighten it again so the final alignment is as precise as a normal one.
    Pose guess = prediction;
    int iterations = icp.iterations;
    bool ok = true;
    for (double threshold = config_.recovery_threshold; ok && threshold > sigma; threshold *= 0.5) {
      IcpOptions wide;
      wide.max_correspondence_distance = 3.0 * threshold;
      wide.kernel_scale = threshold / 3.0;
      wide.max_iterations = config_.max_iterations;
      wide.convergence = config_.convergence;
      const IcpResult r = align_point_to_point(source, map_, guess, wide);
      iterations += r.iterations;
      ok = r.enough_correspondences;
      guess = r.T_target_source;
    }
    if (ok) {
      IcpOptions fine;
      fine.max_correspondence_distance = 3.0 * sigma;
      fine.kernel_scale = sigma / 3.0;
      fine.max_iterations = config_.max_iterations;
      fine.convergence = config_.convergence;
      icp = align_point_to_point(source, map_, guess, fine);
      icp.iterations += iterations;
      quality = alignment_quality(source, map_, icp.T_target_source, config_.inlier_distance);
      result.recovered = true;
    }
  }
  result.iterations = icp.iterations;
  result.inlier_fraction = quality.inlier_fraction();
  if (!icp.enough_correspondences)
    return fail(ScanStatus::kRegistrationFailed,
                fmt::format("ICP found only {} correspondences within {:.2f} m", icp.correspondences, 3.0 * sigma));
  if (quality.inlier_fraction() < config_.min_inlier_fraction)
    return fail(ScanStatus::kRegistrationFailed,
                fmt::format("only {:.0f}% of the scan lies within {:.2f} m of the local map after ICP (need {:.0f}%)",
                            100.0 * quality.inlier_fraction(), config_.inlier_distance,
                            100.0 * config_.min_inlier_fraction));

  result.T_odom_sensor = icp.T_target_source;
  update_threshold(prediction.inverse() * result.T_odom_sensor);
  map_.update(frame, result.T_odom_sensor);
  accept(stamp, result.T_odom_sensor);
  return result;
}

}  // namespace slamvdb::localization
