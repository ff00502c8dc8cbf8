// The surface refinement on its own, on SIMULATED ground: an undulating surface voxelised into
// two 0.25 m lattices 0.10 m apart in height, started where point-to-point ICP locks (the
// lattices together, 0.10 m off in z).
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <tuple>
#include <vector>

#include "slamvdb/sessions/surface_refinement.hpp"

namespace slamvdb::sessions {
namespace {

constexpr double kSurfaceTestVoxel = 0.25;

// Occupied voxel centres of the surface z = h(x, y) sampled densely, in a frame where the
// world's points are at p + offset.
std::vector<Vec3d> surface_test_voxels(const Vec3d& offset) {
  std::set<std::tuple<int, int, int>> keys;
  for (double x = -20.0; x <= 20.0; x += 0.05)
    for (double y = -20.0; y <= 20.0; y += 0.05) {
      const Vec3d p = Vec3d(x, y, 0.6 * std::sin(x / 5.0) + 0.4 * std::cos(y / 4.0)) + offset;
      keys.insert({static_cast<int>(std::floor(p.x() / kSurfaceTestVoxel)),
                   static_cast<int>(std::floor(p.y() / kSurfaceTestVoxel)),
                   static_cast<int>(std::floor(p.z() / kSurfaceTestVoxel))});
    }
  std::vector<Vec3d> out;
  for (const auto& [i, j, k] : keys) out.push_back((Vec3d(i, j, k) + Vec3d::Constant(0.5)) * kSurfaceTestVoxel);
  return out;
}

TEST(SurfaceRefinement, PutsOffsetLatticesOnTheSurface) {
  const std::vector<Vec3d> base = surface_test_voxels(Vec3d::Zero());
  const Vec3d offset(0.0, 0.0, 0.10);  // the other frame: world + offset
  std::vector<Vec3d> other = surface_test_voxels(offset);
  // Keep the middle: the base reaches farther, so that every other point has its surface.
  std::erase_if(other, [](const Vec3d& p) { return std::abs(p.x()) > 15.0 || std::abs(p.y()) > 15.0; });
  Pose locked = Pose::Identity();  // T_base_other as the lattices lock: no vertical shift at all
  const SurfaceRefinementConfig config;
  const SurfacePlanes planes(base, other, config);
  EXPECT_GT(planes.planes(), other.size() / 2);
  const SurfaceRefinement refined = refine_on_surface(other, planes, locked, config);
  ASSERT_TRUE(refined.ok);
  const Vec3d error = refined.T_base_other.translation() + offset;  // truth: T_base_other = -offset
  EXPECT_LT(std::abs(error.z()), 0.03) << error.transpose();
  EXPECT_LT(error.head<2>().norm(), 0.05) << error.transpose();
  EXPECT_LT(Eigen::AngleAxisd(refined.T_base_other.linear()).angle() * 180.0 / M_PI, 0.1);
  std::printf("SIMULATED lattices 0.10 m apart: z error 0.100 m -> %.4f m (%zu correspondences, %d iterations)\n",
              error.z(), refined.correspondences, refined.iterations);
}

}  // namespace
}  // namespace slamvdb::sessions
