#include "slamvdb/synth/lidar_sim.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "slamvdb/synth/world.hpp"

namespace slamvdb::synth {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

SynthWorld short_world() {
  SynthConfig config;
  config.length_m = 20.0;
  return build_synthetic_world(config);
}

TEST(SynthLidar, Os1RayPatternIsColumnMajorOver33Degrees) {
  const LidarModel model;
  const std::vector<Vec3d> rays = model.ray_directions();
  ASSERT_EQ(rays.size(), 64u * 1024u);
  double lo = 1.0, hi = -1.0;
  for (const Vec3d& r : rays) {
    EXPECT_NEAR(r.norm(), 1.0, 1e-12);
    lo = std::min(lo, std::asin(r.z()));
    hi = std::max(hi, std::asin(r.z()));
  }
  EXPECT_NEAR(hi / kDeg, 16.6, 1e-9);
  EXPECT_NEAR(lo / kDeg, -16.6, 1e-9);
  // ray = column * 64 + beam: the first 64 rays share an azimuth and go from top to bottom.
  for (int b = 0; b < 64; ++b) {
    EXPECT_NEAR(std::atan2(rays[b].y(), rays[b].x()), 0.0, 1e-12);
    EXPECT_NEAR(std::asin(rays[b].z()), model.elevation(b), 1e-12);
    if (b > 0) {
      EXPECT_LT(rays[b].z(), rays[b - 1].z());
    }
  }
  EXPECT_NEAR(std::atan2(rays[64 * 256].y(), rays[64 * 256].x()), -0.5 * std::numbers::pi, 1e-12);
}

// Every written point lies where its ray meets the scene, within the range noise, and carries
// the class of that surface: checked by re-casting the ray and by the scene's surface query.
TEST(SynthLidar, EveryPointHasItsSurfacesClassAndRangeWithinNoise) {
  const SynthWorld world = short_world();
  const LidarModel& model = world.config.lidar;
  const std::vector<Vec3d> rays = model.ray_directions();
  for (std::size_t scan_index : {std::size_t{0}, world.scan_poses.size() - 1}) {
    const Pose& T = world.scan_poses[scan_index];
    const SimulatedScan scan = simulate_scan(*world.scene, model, rays, T, 1, scan_index, false);
    ASSERT_EQ(scan.points.size(), scan.labels.size());
    ASSERT_EQ(scan.points.size(), scan.ray_index.size());
    EXPECT_EQ(scan.points.size() + scan.no_returns, rays.size());
    EXPECT_GT(scan.points.size(), rays.size() / 2);
    double noise_sq = 0.0;
    for (std::size_t i = 0; i < scan.points.size(); ++i) {
      const Vec3d p = scan.points[i].head<3>().cast<double>();
      const Vec3d& ray = rays[scan.ray_index[i]];
      const double range = p.norm();
      ASSERT_GE(range, model.min_range);
      ASSERT_LE(range, model.max_range);
      // On its ray: the direction is exact, only the range is noisy.
      ASSERT_NEAR(p.normalized().dot(ray), 1.0, 1e-9);
      const auto truth = world.scene->raycast(T.translation(), T.linear() * ray, model.max_range);
      ASSERT_TRUE(truth.has_value());
      ASSERT_EQ(scan.labels[i], truth->label) << "point " << i;
      ASSERT_LT(std::abs(range - truth->range), 6.0 * model.range_noise_sigma);
      noise_sq += (range - truth->range) * (range - truth->range);
      const std::vector<uint16_t> near = world.scene->surface_classes_near(T * p, 0.15);
      ASSERT_NE(std::find(near.begin(), near.end(), scan.labels[i]), near.end()) << "point " << i;
      ASSERT_GE(scan.points[i].w(), 0.0f);
      ASSERT_LE(scan.points[i].w(), 0.02f);
    }
    EXPECT_NEAR(std::sqrt(noise_sq / scan.points.size()), model.range_noise_sigma, 0.002);
  }
}

TEST(SynthLidar, NoReturnsCanBeKeptAsZeroPointsAndScansAreReproducible) {
  const SynthWorld world = short_world();
  const LidarModel& model = world.config.lidar;
  const std::vector<Vec3d> rays = model.ray_directions();
  const Pose& T = world.scan_poses[3];
  const SimulatedScan kept = simulate_scan(*world.scene, model, rays, T, 1, 3, true);
  ASSERT_EQ(kept.points.size(), rays.size());
  std::size_t zeros = 0;
  for (std::size_t i = 0; i < kept.points.size(); ++i) {
    EXPECT_EQ(kept.ray_index[i], i);
    if (kept.points[i].isZero()) {
      ++zeros;
      EXPECT_EQ(kept.labels[i], 0);
    }
  }
  EXPECT_EQ(zeros, kept.no_returns);
  EXPECT_GT(zeros, 1000u);  // the upper beams see sky

  const SimulatedScan dropped = simulate_scan(*world.scene, model, rays, T, 1, 3, false);
  EXPECT_EQ(dropped.points.size(), rays.size() - kept.no_returns);
  for (std::size_t i = 0; i < dropped.points.size(); ++i)
    ASSERT_TRUE(dropped.points[i] == kept.points[dropped.ray_index[i]]) << "same noise with or without zeros";

  const SimulatedScan again = simulate_scan(*world.scene, model, rays, T, 1, 3, false);
  EXPECT_TRUE(std::equal(again.points.begin(), again.points.end(), dropped.points.begin()));
  const SimulatedScan other = simulate_scan(*world.scene, model, rays, T, 1, 4, false);
  EXPECT_FALSE(std::equal(other.points.begin(), other.points.end(), dropped.points.begin()));
}


// SIMULATED sweep: each column from the pose at its own time, with that time per point. Without
// motion it is the scan from one pose; with motion every point lies on the scene seen from its
// column's pose.
TEST(SynthLidar, SweptScanCastsEachColumnFromThePoseAtItsTime) {
  const SynthWorld world = short_world();
  LidarModel model = world.config.lidar;
  model.columns = 256;
  const std::vector<Vec3d> rays = model.ray_directions();
  const SimulatedScan still = simulate_swept_scan(
      *world.scene, model, rays, [&](double) { return world.scan_poses[2]; }, 0.1, 1, 2, false);
  const SimulatedScan single = simulate_scan(*world.scene, model, rays, world.scan_poses[2], 1, 2, false);
  ASSERT_EQ(still.points.size(), single.points.size());
  EXPECT_TRUE(std::equal(still.points.begin(), still.points.end(), single.points.begin()));
  EXPECT_TRUE(single.times.empty());
  ASSERT_EQ(still.times.size(), still.points.size());
  for (std::size_t i = 0; i < still.times.size(); ++i) {
    const std::size_t column = still.ray_index[i] / model.beams;
    ASSERT_FLOAT_EQ(still.times[i], static_cast<float>(0.1 * column / model.columns));
  }
  // Turning fast (the pose at each time along a 90 deg/s yaw about the stamp's pose).
  const auto turning = [&](double t) {
    Pose T = world.scan_poses[2];
    T.linear() = T.linear() * Eigen::AngleAxisd(0.5 * std::numbers::pi * t, Vec3d::UnitZ()).toRotationMatrix();
    return T;
  };
  const SimulatedScan swept = simulate_swept_scan(*world.scene, model, rays, turning, 0.1, 1, 2, false);
  EXPECT_GT(swept.points.size(), rays.size() / 2);
  for (std::size_t i = 0; i < swept.points.size(); i += 7) {
    const Pose T = turning(swept.times[i]);
    const Vec3d p = swept.points[i].head<3>().cast<double>();
    const auto truth = world.scene->raycast(T.translation(), T.linear() * rays[swept.ray_index[i]], model.max_range);
    ASSERT_TRUE(truth.has_value()) << i;
    ASSERT_LT(std::abs(p.norm() - truth->range), 6.0 * model.range_noise_sigma) << i;
  }
}

}  // namespace
}  // namespace slamvdb::synth
