#include "slamvdb/localization/odometry.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "slamvdb/core/se3.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/simulated_drive.hpp"

namespace slamvdb::localization {
namespace {

using testing::simulate_drive;

// Final position error of odometry over a SIMULATED drive, relative to its length.
struct DriftRun {
  double drift_percent = 0.0, final_error = 0.0, length = 0.0, seconds = 0.0;
  std::size_t not_ok = 0;
};
DriftRun run_drift(const testing::SimulatedDrive& drive) {
  LidarOdometry odometry;
  DriftRun run;
  const Pose T_world_odom = drive.T_world_sensor.front();
  Pose last = Pose::Identity();
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < drive.scans.size(); ++i) {
    const OdometryResult r = odometry.register_scan(drive.stamps[i], drive.scans[i]);
    run.not_ok += r.status != ScanStatus::kOk;
    last = r.T_odom_sensor;
  }
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  run.final_error = ((T_world_odom * last).translation() - drive.T_world_sensor.back().translation()).norm();
  run.length = drive.path_length_m;
  run.drift_percent = 100.0 * run.final_error / run.length;
  return run;
}

TEST(LidarOdometry, DriftBelowOnePercentOnASimulatedDrive) {
  synth::SynthConfig config;
  config.length_m = 100.0;
  // The sanitizer run registers the first 60 scans (slamvdb/testing/test_scale.hpp).
  const auto drive = simulate_drive(config, 0, slamvdb::testing::test_size<std::size_t>(0, 60));
  const DriftRun run = run_drift(drive);
  std::printf("SIMULATED %.0f m, %zu scans: final error %.3f m = %.3f%% of the distance, %.1f Hz\n", run.length,
              drive.scans.size(), run.final_error, run.drift_percent, drive.scans.size() / run.seconds);
  EXPECT_EQ(run.not_ok, 0u);
  EXPECT_LT(run.drift_percent, 1.0);
}

// Short loops of other seeds: before the simulator kept hand-placed objects off the whole loop,
// seeds 3 and 5 drove through the yard's building and odometry lost track there.
TEST(LidarOdometry, TracksShortLoopsOfOtherSeeds) {
  // The sanitizer run registers seed 3 alone (slamvdb/testing/test_scale.hpp): the same code as seed 5.
  for (const uint64_t seed : slamvdb::testing::test_size<std::vector<uint64_t>>({3u, 5u}, {3u})) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    synth::SynthConfig config;
    config.seed = seed;
    config.length_m = 100.0;
    config.min_loop_m = 70.0;
    config.lidar.columns = 512;
    const DriftRun run = run_drift(simulate_drive(config, 0, slamvdb::testing::test_size<std::size_t>(0, 60)));
    EXPECT_LE(run.not_ok, 1u);
    EXPECT_LT(run.drift_percent, 1.0);
  }
}

synth::SynthConfig short_drive_config() {
  synth::SynthConfig config;
  config.length_m = 60.0;
  config.speed_mps = 10.0;
  config.lidar.columns = 512;
  return config;
}

double position_error(const testing::SimulatedDrive& drive, std::size_t i, const Pose& T_odom_sensor) {
  return ((drive.T_world_sensor.front() * T_odom_sensor).translation() - drive.T_world_sensor[i].translation()).norm();
}

TEST(LidarOdometry, BadScansAreCountedAndNeverGetASilentPose) {
  const auto drive = simulate_drive(short_drive_config(), 0, 40);
  LidarOdometry odometry;
  for (std::size_t i = 0; i < 10; ++i) ASSERT_EQ(odometry.register_scan(drive.stamps[i], drive.scans[i]).status, ScanStatus::kOk);

  // Very few points.
  const std::vector<Vec3f> few(drive.scans[10].begin(), drive.scans[10].begin() + 50);
  OdometryResult r = odometry.register_scan(drive.stamps[10], few);
  EXPECT_EQ(r.status, ScanStatus::kTooFewPoints);
  EXPECT_TRUE(r.predicted_only);
  EXPECT_NE(r.reason.find("50 valid points"), std::string::npos) << r.reason;
  EXPECT_LT(position_error(drive, 10, r.T_odom_sensor), 0.3) << "the prediction stands in";

  // A scan of NaNs.
  const std::vector<Vec3f> nans(drive.scans[11].size(), Vec3f::Constant(std::numeric_limits<float>::quiet_NaN()));
  r = odometry.register_scan(drive.stamps[11], nans);
  EXPECT_EQ(r.status, ScanStatus::kTooFewPoints);
  EXPECT_EQ(r.non_finite_points, nans.size());

  // Registration resumes on the next good scan.
  r = odometry.register_scan(drive.stamps[12], drive.scans[12]);
  EXPECT_EQ(r.status, ScanStatus::kOk);
  EXPECT_LT(position_error(drive, 12, r.T_odom_sensor), 0.1);

  // Dropped scans with true stamps: the prediction bridges the gap in time.
  r = odometry.register_scan(drive.stamps[17], drive.scans[17]);
  EXPECT_EQ(r.status, ScanStatus::kOk);
  EXPECT_LT(position_error(drive, 17, r.T_odom_sensor), 0.1);

  // A sudden jump of 10 m the stamps do not explain: either registered correctly (after a wide
  // retry) or reported, never a wrong pose passed as ok.
  r = odometry.register_scan(drive.stamps[18], drive.scans[28]);
  if (r.status == ScanStatus::kOk)
    EXPECT_LT(position_error(drive, 28, r.T_odom_sensor), 0.3);
  else
    EXPECT_TRUE(r.predicted_only);
  std::printf("sudden 10 m jump: %s%s, position error %.2f m\n", to_string(r.status), r.recovered ? " (recovered)" : "",
              position_error(drive, 28, r.T_odom_sensor));

  // Stamps must increase.
  EXPECT_NE(slamvdb::testing::error_of([&] { odometry.register_scan(drive.stamps[0], drive.scans[0]); }), "");
  EXPECT_NE(slamvdb::testing::error_of([&] { OdometryConfig c; c.voxel_size = -1; LidarOdometry bad(c); }), "");
}

TEST(LidarOdometry, DeskewsAMovingSweep) {
  // A sweep taken while moving at 10 m/s: points captured over 0.1 s are each seen from where the
  // sensor was at their own time. With per-point times the odometry undoes that.
  const auto drive = simulate_drive(short_drive_config(), 0, 12);
  LidarOdometry with_times, without_times;
  double error_with = 0.0, error_without = 0.0;
  for (std::size_t i = 0; i < drive.scans.size(); ++i) {
    std::vector<float> times(drive.scans[i].size());
    std::vector<Vec3f> skewed(drive.scans[i].size());
    for (std::size_t k = 0; k < times.size(); ++k) {
      // Azimuth order as the capture order; a point at time t was seen from 1 m * (t - 0.5) ahead.
      const Vec3f& p = drive.scans[i][k];
      const float t = static_cast<float>((std::atan2(p.y(), p.x()) + std::numbers::pi) / (2.0 * std::numbers::pi));
      times[k] = t;
      // Sensor moving along its own -x (RELLIS mounting: x points backwards) by 1 m per sweep.
      skewed[k] = p - Vec3f(-(t - 0.5f), 0.0f, 0.0f);
    }
    const auto a = with_times.register_scan(drive.stamps[i], skewed, &times);
    const auto b = without_times.register_scan(drive.stamps[i], skewed);
    error_with = position_error(drive, i, a.T_odom_sensor);
    error_without = position_error(drive, i, b.T_odom_sensor);
  }
  EXPECT_LT(error_with, 0.15);
  EXPECT_LE(error_with, error_without + 0.02);
}

}  // namespace
}  // namespace slamvdb::localization
