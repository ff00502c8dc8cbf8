// The surface refinement on its own, on SIMULATED ground: an undulating surface voxelised into
// two 0.25 m lattices 0.10 m apart in height, started where point-to-point ICP locks (the
// lattices together, 0.10 m off in z).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>
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

// Each plane is fitted to every base point within the normal radius, whichever cell it lies in
// (the constructor leaves out the cells beyond the radius): the same centroids and normals as a
// search over all the points, on SIMULATED points off any lattice, far from the origin, many of
// them just inside or outside the radius of another.
TEST(SurfaceRefinement, PlanesUseEveryBasePointWithinTheRadius) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> jitter(-0.04, 0.04);
  const Vec3d origin(1000.3, -2000.7, 30.1);
  std::vector<Vec3d> base;
  for (double x = 0.0; x < 5.0; x += 0.1)
    for (double y = 0.0; y < 5.0; y += 0.1)
      base.push_back(origin + Vec3d(x + jitter(rng), y + jitter(rng), 0.3 * std::sin(x) + 0.1 * y + jitter(rng)));
  SurfaceRefinementConfig config;
  config.normal_radius = 0.45;
  const SurfacePlanes planes(base, base, config);
  const double r2 = config.normal_radius * config.normal_radius;
  std::size_t compared = 0;
  for (const Vec3d& p : base) {
    Vec3d sum = Vec3d::Zero();
    Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
    std::size_t n = 0;
    for (const Vec3d& q : base) {
      const Vec3d d = q - p;
      if (d.squaredNorm() > r2) continue;
      sum += d, outer += d * d.transpose(), ++n;
    }
    ASSERT_GE(n, config.min_neighbours);
    const Vec3d mean = sum / static_cast<double>(n);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(outer / static_cast<double>(n) - mean * mean.transpose());
    // Near the patch's edges a neighbourhood may be too narrow for a plane: the same rule decides.
    const bool flat = solver.eigenvalues()(1) >= 0.25 * solver.eigenvalues()(2);
    Vec3d centroid, normal;
    ASSERT_EQ(planes.nearest(p, centroid, normal), flat);  // the point's own plane
    if (!flat) continue;
    EXPECT_LT((centroid - (p + mean)).norm(), 1e-9) << "at " << (p - origin).transpose() << " with " << n << " points";
    EXPECT_GT(std::abs(normal.dot(solver.eigenvectors().col(0))), 1.0 - 1e-9);
    ++compared;
  }
  EXPECT_EQ(planes.planes(), compared);
  EXPECT_GT(compared, base.size() * 9 / 10);
}

}  // namespace
}  // namespace slamvdb::sessions
