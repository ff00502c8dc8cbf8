#include "slamvdb/synth/trajectory_sim.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <set>

#include "slamvdb/core/error.hpp"
#include "slamvdb/synth/camera_sim.hpp"
#include "slamvdb/synth/world.hpp"

namespace slamvdb::synth {
namespace {

TEST(SynthTrajectory, LoopHasTheRequestedPerimeterAndCloses) {
  const LoopPath path(200.0, 9);
  double length = 0.0;
  for (double s = 0.0; s < 200.0; s += 0.05) length += (path.point(s + 0.05) - path.point(s)).norm();
  EXPECT_NEAR(length, 200.0, 0.05);
  EXPECT_LT(path.point(0.0).norm(), 1e-9);  // starts at the origin
  EXPECT_LT((path.point(200.0) - path.point(0.0)).norm(), 1e-6);
  EXPECT_LT((path.point(237.0) - path.point(37.0)).norm(), 1e-6);
  for (double s : {0.0, 10.0, 77.7, 150.0}) {
    const Eigen::Vector2d fd = (path.point(s + 0.01) - path.point(s - 0.01)) / 0.02;
    EXPECT_NEAR(fd.dot(path.tangent(s)), 1.0, 1e-3);
    EXPECT_NEAR(path.distance(path.at(s, 4.0)), 4.0, 0.05);
  }
}

TEST(SynthTrajectory, DefaultDriveIsLongEnoughRevisitsAndFollowsTheGround) {
  const SynthWorld world = build_synthetic_world(SynthConfig{});
  ASSERT_GE(world.path_length_m, 320.0);
  EXPECT_LT(world.path_length_m, 322.0);
  const std::size_t n = world.scan_poses.size();
  EXPECT_EQ(n, world.scan_stamps.size());
  // Revisit: a late pose within 3 m of an early one more than 100 m of driving before it.
  std::vector<double> along(n, 0.0);
  for (std::size_t i = 1; i < n; ++i)
    along[i] = along[i - 1] + (world.scan_poses[i].translation() - world.scan_poses[i - 1].translation()).norm();
  double best = 1e9;
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < j && along[j] - along[i] > 100.0; ++i)
      best = std::min(best, (world.scan_poses[j].translation() - world.scan_poses[i].translation()).norm());
  EXPECT_LT(best, 3.0);

  const Terrain& terrain = world.scene->terrain();
  for (std::size_t i = 0; i < n; ++i) {
    const Pose& T = world.scan_poses[i];
    const Vec3d p = T.translation();
    EXPECT_NEAR(p.z() - terrain.height(p.x(), p.y()), 1.5, 0.1) << "scan " << i;
    // The LiDAR's z axis follows the ground's normal (roll and pitch from the terrain).
    EXPECT_GT(T.linear().col(2).dot(terrain.normal(p.x(), p.y())), std::cos(3.0 * std::numbers::pi / 180.0))
        << "scan " << i;
    EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-9);
    if (i > 0) {
      // Smooth heading: under 6 degrees of turn per 0.1 s, and the LiDAR's x points backwards.
      const Eigen::Matrix3d dR = world.scan_poses[i - 1].linear().transpose() * T.linear();
      EXPECT_LT(Eigen::AngleAxisd(dR).angle(), 6.0 * std::numbers::pi / 180.0) << "scan " << i;
      const Vec3d motion = p - world.scan_poses[i - 1].translation();
      EXPECT_LT(motion.normalized().dot(T.linear().col(0)), -0.95) << "scan " << i;
      EXPECT_NEAR(motion.norm(), 0.5, 0.05);
      EXPECT_NEAR(world.scan_stamps[i] - world.scan_stamps[i - 1], 0.1, 1e-6);
    }
  }
  // The terrain is not flat: the drive pitches and rolls by a few degrees.
  double max_tilt = 0.0;
  for (const Pose& T : world.scan_poses) max_tilt = std::max(max_tilt, std::acos(T.linear()(2, 2)));
  EXPECT_GT(max_tilt, 2.0 * std::numbers::pi / 180.0);
  EXPECT_LT(max_tilt, 20.0 * std::numbers::pi / 180.0);
}

TEST(SynthTrajectory, CameraStampsAreOwnRateNotAlignedAndInsideTheScans) {
  SynthConfig config;
  config.length_m = 60.0;
  const SynthWorld world = build_synthetic_world(config);
  const auto& cam = world.camera_stamps_ms;
  ASSERT_GT(cam.size(), 20u);
  const std::set<int64_t> scan_ms = [&] {
    std::set<int64_t> s;
    for (double t : world.scan_stamps) s.insert(std::llround(t * 1000.0));
    return s;
  }();
  for (std::size_t k = 0; k < cam.size(); ++k) {
    EXPECT_EQ(scan_ms.count(cam[k]), 0u) << "camera frame " << k << " shares a scan stamp";
    EXPECT_GE(cam[k] / 1000.0, world.scan_stamps.front());
    EXPECT_LE(cam[k] / 1000.0, world.scan_stamps.back());
    if (k > 0) {
      EXPECT_NEAR(cam[k] - cam[k - 1], 200, 5) << "5 Hz with a few ms of jitter";
    }
  }
  // Jitter: the intervals are not all equal.
  std::set<int64_t> intervals;
  for (std::size_t k = 1; k < cam.size(); ++k) intervals.insert(cam[k] - cam[k - 1]);
  EXPECT_GT(intervals.size(), 2u);
}

// Every listed class is actually seen along the default drive (sparse LiDAR rays and camera rays).
TEST(SynthTrajectory, DefaultDriveSeesEveryClass) {
  const SynthWorld world = build_synthetic_world(SynthConfig{});
  LidarModel sparse = world.config.lidar;
  sparse.columns = 256;
  const std::vector<Vec3d> rays = sparse.ray_directions();
  std::set<uint16_t> seen;
  for (std::size_t i = 0; i < world.scan_poses.size(); i += 5) {
    const Pose& T = world.scan_poses[i];
    for (const Vec3d& r : rays)
      if (const auto hit = world.scene->raycast(T.translation(), T.linear() * r, sparse.max_range))
        seen.insert(hit->label);
  }
  const CameraSimulator camera(world.camera);
  const Pose T_world_camera = world.T_world_camera(world.camera_stamps_ms[0] / 1000.0);
  if (!world.scene->raycast(T_world_camera.translation(), T_world_camera.linear() * camera.ray(320, 0), 200.0))
    seen.insert(kSkyClass);
  const std::set<uint16_t> expected = {1, 3, 4, 5, 7, 8, 10, 12, 15, 17, 18, 19, 23, 27, 31, 33, 34};
  EXPECT_EQ(seen, expected);
}

// Two drives over one scene (issue 23): the same seed and loop length give the same scene and
// trail whatever the drives' lengths; a drive can start anywhere on the loop, drive it clockwise,
// and draw its own sensor noise and rig errors.
TEST(SynthTrajectory, SecondDriveOnTheSameLoopStartsElsewhereAndDrivesItBackwards) {
  SynthConfig forward;
  forward.loop_length_m = 200.0;
  forward.length_m = 80.0;
  SynthConfig back = forward;
  back.length_m = 60.0;
  back.start_offset_m = 70.0;
  back.reverse = true;
  back.noise_seed = 9;
  const SynthWorld a = build_synthetic_world(forward), b = build_synthetic_world(back);
  EXPECT_EQ(a.trajectory.path().perimeter(), 200.0);
  EXPECT_EQ(b.trajectory.path().perimeter(), 200.0);
  ASSERT_EQ(a.scene->objects().size(), b.scene->objects().size()) << "one scene";
  for (std::size_t i = 0; i < a.scene->objects().size(); i += 7)
    EXPECT_EQ(a.scene->objects()[i].bounds().min(), b.scene->objects()[i].bounds().min());
  // B starts 70 m along A's trail and drives towards A's start, facing the other way.
  const double speed = forward.speed_mps;
  const Pose a_at_70 = a.trajectory.T_world_lidar(70.0 / speed), b_start = b.scan_poses.front();
  EXPECT_LT((a_at_70.translation() - b_start.translation()).norm(), 1e-6);
  EXPECT_LT(a_at_70.linear().col(0).dot(b_start.linear().col(0)), -0.99);
  const Pose a_at_30 = a.trajectory.T_world_lidar(30.0 / speed), b_after_40 = b.trajectory.T_world_lidar(40.0 / speed);
  EXPECT_LT((a_at_30.translation() - b_after_40.translation()).norm(), 1e-6);
  // Its own noise: the rig error differs (drawn from noise_seed), the default is the seed.
  EXPECT_GT((a.T_lidar_camera_true.translation() - b.T_lidar_camera_true.translation()).norm(), 1e-3);
  EXPECT_EQ(forward.sensor_seed(), forward.seed);
  EXPECT_EQ(back.sensor_seed(), 9u);
  back.loop_length_m = 30.0;
  EXPECT_THROW(build_synthetic_world(back), Error);
}

TEST(SynthTrajectory, BadSettingsAreRejectedWithTheirName) {
  SynthConfig config;
  config.speed_mps = -1.0;
  try {
    build_synthetic_world(config);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("speed"), std::string::npos);
  }
  config = SynthConfig{};
  config.image_width = 4;
  EXPECT_THROW(build_synthetic_world(config), Error);
  config = SynthConfig{};
  config.lidar.fov_up_deg = -20.0;
  EXPECT_THROW(build_synthetic_world(config), Error);
}

}  // namespace
}  // namespace slamvdb::synth
