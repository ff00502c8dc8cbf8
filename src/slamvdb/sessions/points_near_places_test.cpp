#include "slamvdb/sessions/points_near_places.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb::sessions {
namespace {

// Every point of every submap against every centre: what world_points_near must return, in
// the same order.
std::vector<Vec3d> every_point_near(const std::vector<std::vector<Vec3d>>& clouds, const std::vector<Pose>& T_world_submaps,
                                    const std::vector<Eigen::Vector2d>& centres, double radius, std::optional<std::size_t> only) {
  std::vector<Vec3d> out;
  for (std::size_t i = 0; i < clouds.size(); ++i) {
    if (only && *only != i) continue;
    for (const Vec3d& p : clouds[i]) {
      const Vec3d x = T_world_submaps[i] * p;
      if (std::any_of(centres.begin(), centres.end(),
                      [&](const Eigen::Vector2d& c) { return (x.head<2>() - c).squaredNorm() <= radius * radius; }))
        out.push_back(x);
    }
  }
  return out;
}

TEST(SubmapClouds, PointsNearPlacesAreThoseOfTheTestOfEveryPointInTheSameOrder) {
  // Ten submaps of a turning drive, 40 m apart, each a 60 m square of points (submap frame)
  // around its anchor; centres near a few of them (and one on a submap's edge, one far away).
  std::vector<std::vector<Vec3d>> clouds(10);
  std::vector<Pose> T_world_submaps(10, Pose::Identity());
  for (std::size_t i = 0; i < clouds.size(); ++i) {
    for (double x = -30.0; x <= 30.0; x += 0.7)
      for (double y = -30.0; y <= 30.0; y += 0.9) clouds[i].emplace_back(x, y, 0.1 * std::sin(x + i));
    T_world_submaps[i].linear() = Eigen::AngleAxisd(0.3 * static_cast<double>(i), Vec3d::UnitZ()).toRotationMatrix();
    T_world_submaps[i].translation() = Vec3d(40.0 * static_cast<double>(i), 5.0 * std::sin(i), 1.0);
  }
  clouds[4].clear();  // a submap with no points
  // (38, 0): 8.5 m beyond submap 0's last points (x <= 29.5, not turned), so with radius 10 m
  // it reaches only a strip of them: a test of submaps by bounds cut short would lose it.
  const std::vector<Eigen::Vector2d> centres = {{80.0, 3.0}, {95.0, -10.0}, {270.0, 40.0}, {38.0, 0.0}, {5000.0, 5000.0}};
  const SubmapClouds submaps(clouds);
  ASSERT_EQ(submaps.size(), 10u);
  for (const double radius : {10.0, 30.0}) {
    const std::vector<Vec3d> expected = every_point_near(clouds, T_world_submaps, centres, radius, {});
    ASSERT_GT(expected.size(), 1000u);
    EXPECT_EQ(submaps.world_points_near(T_world_submaps, centres, radius), expected) << "radius " << radius;
    for (const std::size_t only : {std::size_t{0}, std::size_t{1}, std::size_t{2}, std::size_t{9}})
      EXPECT_EQ(submaps.world_points_near(T_world_submaps, centres, radius, only),
                every_point_near(clouds, T_world_submaps, centres, radius, only))
          << "radius " << radius << ", submap " << only;
  }
  EXPECT_FALSE(submaps.world_points_near(T_world_submaps, {{38.0, 0.0}}, 10.0, std::size_t{0}).empty());
  EXPECT_TRUE(submaps.world_points_near(T_world_submaps, {{5000.0, 5000.0}}, 30.0).empty());
  EXPECT_THROW(submaps.world_points_near({Pose::Identity()}, centres, 10.0), Error);
}

}  // namespace
}  // namespace slamvdb::sessions
