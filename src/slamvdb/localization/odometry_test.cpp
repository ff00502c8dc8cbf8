#include "slamvdb/localization/odometry.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>

#include "slamvdb/core/se3.hpp"
#include "slamvdb/localization/simulated_drive_for_tests.hpp"
#include "slamvdb/testing/error_of.hpp"

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
  const auto drive = simulate_drive(config);
  const DriftRun run = run_drift(drive);
  std::printf("SIMULATED %.0f m, %zu scans: final error %.3f m = %.3f%% of the distance, %.1f Hz\n", run.length,
              drive.scans.size(), run.final_error, run.drift_percent, drive.scans.size() / run.seconds);
  EXPECT_EQ(run.not_ok, 0u);
  EXPECT_LT(run.drift_percent, 1.0);
}

}  // namespace
}  // namespace slamvdb::localization
