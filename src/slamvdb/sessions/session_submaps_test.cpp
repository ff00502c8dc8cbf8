#include "slamvdb/sessions/session_submaps.hpp"

#include <gtest/gtest.h>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::sessions {
namespace {

TEST(SessionSubmaps, ReadsEachSubmapsAnchorAndOccupiedVoxelCentres) {
  // A wall 5 m ahead of the sensor, scanned from two places far enough apart for two submaps.
  MapParams params;
  params.submap_length = 10.0;
  SemanticMap map(params);
  std::vector<Vec3f> wall;
  for (float y = -2.0f; y <= 2.0f; y += 0.1f)
    for (float z = 0.0f; z <= 2.0f; z += 0.1f) wall.emplace_back(5.0f, y, z);
  Pose T_world_sensor = Pose::Identity();
  T_world_sensor.translation() = Vec3d(0.3, 0.1, 1.0);
  map.integrate_scan(0.0, wall, T_world_sensor);
  T_world_sensor.translation() = Vec3d(20.3, 0.1, 1.0);
  map.integrate_scan(1.0, wall, T_world_sensor);

  const std::vector<SessionSubmap> submaps = session_submaps(map);
  const std::vector<SubmapInfo> infos = map.submaps();
  ASSERT_EQ(submaps.size(), 2u);
  ASSERT_EQ(infos.size(), 2u);
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    EXPECT_EQ(submaps[i].id, infos[i].id);
    EXPECT_TRUE(submaps[i].T_world_submap.isApprox(infos[i].T_world_submap));
    ASSERT_GT(submaps[i].occupied_submap.size(), 100u);
    const double wall_x = i == 0 ? 5.3 : 25.3;  // world
    for (const Vec3f& p : submaps[i].occupied_submap) {
      const Vec3d world = submaps[i].T_world_submap * p.cast<double>();
      EXPECT_NEAR(world.x(), wall_x, params.occupancy.voxel_size) << "an occupied voxel off the wall";
    }
  }
}

}  // namespace
}  // namespace slamvdb::sessions
