#include "slamvdb/localization/loop_closure.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "slamvdb/localization/odometry.hpp"
#include "slamvdb/localization/trajectory_metrics.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/simulated_drive.hpp"

namespace slamvdb::localization {
namespace {

using testing::simulate_drive;
using testing::SimulatedDrive;

// A SIMULATED drive around a loop that revisits its start, small enough for a unit test:
// 512 columns (256 in the sanitizer run: slamvdb/testing/test_scale.hpp), 10 m/s (1 m between scans).
synth::SynthConfig looping_drive_config() {
  synth::SynthConfig config;
  config.length_m = 150.0;
  config.speed_mps = 10.0;
  config.lidar.columns = slamvdb::testing::test_size(512, 256);
  return config;
}

// Odometry over the drive, then a yaw bias of `bias_deg_per_m` injected into every step, so the
// loop closure has a known drift to remove.
std::vector<Pose> odometry_with_injected_drift(const SimulatedDrive& drive, double bias_deg_per_m) {
  LidarOdometry odometry;
  std::vector<Pose> poses;
  Pose biased = Pose::Identity(), previous = Pose::Identity();
  for (std::size_t i = 0; i < drive.scans.size(); ++i) {
    const OdometryResult r = odometry.register_scan(drive.stamps[i], drive.scans[i]);
    EXPECT_EQ(r.status, ScanStatus::kOk) << i;
    const Pose step = previous.inverse() * r.T_odom_sensor;
    previous = r.T_odom_sensor;
    Pose bias = Pose::Identity();
    bias.linear() = Eigen::AngleAxisd(bias_deg_per_m * std::numbers::pi / 180.0 * step.translation().norm(),
                                      Vec3d::UnitZ()).toRotationMatrix();
    biased = biased * step * bias;
    poses.push_back(biased);
  }
  return poses;
}

std::vector<Pose> in_world(const SimulatedDrive& drive, const std::vector<Pose>& T_odom) {
  std::vector<Pose> out;
  for (const Pose& T : T_odom) out.push_back(drive.T_world_sensor.front() * T);
  return out;
}

TEST(LoopClosingMapper, RemovesInjectedDriftOnASimulatedLoop) {
  // In the sanitizer run a 100 m drive around a 70 m loop (103 scans, not 151: the odometry and the
  // mapper register every scan, 62 s under ASan), with twice the bias per metre so that the drift
  // to remove is as large (ATE 1.3 m, measured with `slam --sim-odometry-drift 20` on this drive).
  synth::SynthConfig config = looping_drive_config();
  config.length_m = slamvdb::testing::test_size(config.length_m, 100.0);
  config.min_loop_m = slamvdb::testing::test_size(config.min_loop_m, 70.0);
  const SimulatedDrive drive = simulate_drive(config);
  const std::vector<Pose> odom = odometry_with_injected_drift(drive, slamvdb::testing::test_size(0.1, 0.2));
  LoopClosingMapper mapper;
  std::size_t attempts_seen = 0;
  for (std::size_t i = 0; i < drive.scans.size(); ++i) {
    const AddScanResult r = mapper.add_scan(drive.stamps[i], odom[i], drive.scans[i]);
    attempts_seen += r.attempts.size();
  }
  EXPECT_EQ(attempts_seen, mapper.loops().size() + mapper.rejected_total());
  std::vector<Pose> corrected;
  for (std::size_t i = 0; i < odom.size(); ++i) corrected.push_back(mapper.corrected_pose(drive.stamps[i], odom[i]));
  const AteResult before = absolute_trajectory_error(in_world(drive, odom), drive.T_world_sensor);
  const AteResult after = absolute_trajectory_error(corrected, drive.T_world_sensor);
  std::printf("SIMULATED %.0f m loop, %zu keyframes: %zu loops accepted, %zu rejected; ATE %.3f m -> %.3f m\n",
              drive.path_length_m, mapper.keyframes().size(), mapper.loops().size(), mapper.rejected_total(),
              before.rmse, after.rmse);
  EXPECT_GE(mapper.loops().size(), 1u);
  EXPECT_GT(before.rmse, 1.0);  // the injected drift is real ...
  EXPECT_LT(after.rmse, 0.3);   // ... and the loop removes it
  // Every accepted loop agrees with the ground truth.
  for (const LoopClosure& loop : mapper.loops()) {
    const auto pose_at = [&](double stamp) {
      return drive.T_world_sensor[std::find(drive.stamps.begin(), drive.stamps.end(), stamp) - drive.stamps.begin()];
    };
    const Pose truth = pose_at(loop.candidate_stamp).inverse() * pose_at(loop.query_stamp);
    EXPECT_LT((truth.inverse() * loop.T_candidate_query).translation().norm(), 0.2);
    EXPECT_GE(loop.overlap, mapper.config().min_overlap);
  }
}

TEST(LoopClosingMapper, NoFalseLoopAmongRepeatedLookAlikePlaces) {
  synth::SynthConfig config = looping_drive_config();
  config.scene = synth::SceneKind::kRepeatedPlaces;  // the same objects every 30 m
  config.min_loop_m = 400.0;                         // longer than the drive: no place is revisited
  // Three look-alike places in the sanitizer run.
  const SimulatedDrive drive = simulate_drive(config, 0, slamvdb::testing::test_size<std::size_t>(0, 100));
  LidarOdometry odometry;
  LoopClosingMapper mapper;
  std::size_t scan_context_candidates = 0;
  for (std::size_t i = 0; i < drive.scans.size(); ++i) {
    const OdometryResult r = odometry.register_scan(drive.stamps[i], drive.scans[i]);
    for (const LoopAttempt& a : mapper.add_scan(drive.stamps[i], r.T_odom_sensor, drive.scans[i]).attempts)
      scan_context_candidates += a.from_scan_context;
  }
  std::printf("SIMULATED repeated places, %.0f m: %zu ScanContext candidates, %zu loops accepted, rejected:",
              drive.path_length_m, scan_context_candidates, mapper.loops().size());
  for (std::size_t k = 0; k < mapper.rejections().size(); ++k)
    std::printf(" %s %zu", to_string(static_cast<LoopRejection>(k)), mapper.rejections()[k]);
  std::printf("\n");
  EXPECT_GT(scan_context_candidates, 0u);  // the look-alikes do get proposed ...
  EXPECT_EQ(mapper.loops().size(), 0u);    // ... and none is accepted
}

TEST(LoopClosingMapper, VerificationRejectsAWrongCandidate) {
  // The first 40 m of a SIMULATED drive, then scans from 60-80 m further on whose odometry claims
  // they are back at the start: proximity proposes the start keyframes, ICP verification must
  // reject them.
  const SimulatedDrive drive = simulate_drive(looping_drive_config(), 0, 100);
  LoopClosingMapper mapper;
  for (std::size_t i = 0; i < 40; ++i)
    mapper.add_scan(drive.stamps[i], drive.T_world_sensor.front().inverse() * drive.T_world_sensor[i], drive.scans[i]);
  std::size_t attempts = 0;
  for (std::size_t i = 60; i < 80; ++i) {
    // Poses back at the start (the place the odometry wrongly believes it is), on a path long enough.
    const Pose claimed = drive.T_world_sensor.front().inverse() * drive.T_world_sensor[i - 60];
    Pose T_odom = claimed;
    const AddScanResult r = mapper.add_scan(drive.stamps[i] + 100.0, T_odom, drive.scans[i]);
    attempts += r.attempts.size();
  }
  EXPECT_GT(attempts, 0u);
  EXPECT_EQ(mapper.loops().size(), 0u);
  EXPECT_EQ(mapper.rejected_total(), attempts);
  EXPECT_EQ(mapper.rejections()[static_cast<std::size_t>(LoopRejection::kInconsistentWithOdometry)], 0u)
      << "rejected by the geometry, not by the odometry-consistency test";
}

TEST(LoopClosingMapper, CorrectionIsInterpolatedBetweenKeyframes) {
  LoopClosingMapper mapper;
  EXPECT_TRUE(mapper.correction_at(5.0).isApprox(Pose::Identity()));
  EXPECT_NE(slamvdb::testing::error_of([&] {
              mapper.add_scan(1.0, Pose::Identity(), {});
              mapper.add_scan(1.0, Pose::Identity(), {});
            }),
            "");
}

}  // namespace
}  // namespace slamvdb::localization
