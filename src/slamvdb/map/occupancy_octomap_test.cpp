// The occupancy update is OctoMap's rule; this checks it voxel by voxel against OctoMap itself.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include "slamvdb/map/occupancy_grid.hpp"

namespace slamvdb {
namespace {

// A 64 x `columns` spinning-LiDAR pattern hitting a tilted ground plane and two walls, 1.5 m up.
std::vector<Vec3f> ring_scan(std::mt19937& rng, int columns) {
  std::normal_distribution<float> noise(0.0f, 0.02f);
  std::vector<Vec3f> pts;
  for (int r = 0; r < 64; ++r) {
    const double el = (-16.6 + 33.2 * r / 63.0) * M_PI / 180.0;
    for (int c = 0; c < columns; ++c) {
      const double az = 2 * M_PI * c / columns;
      const Vec3d d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      double t = std::numeric_limits<double>::infinity();
      if (d.z() < -1e-3) t = 1.5 / (-d.z() + 0.05 * d.x());     // ground z = -1.5 + 0.05 x
      if (d.x() > 1e-3) t = std::min(t, 18.0 / d.x());           // wall at x = 18
      if (d.y() < -1e-3) t = std::min(t, 9.0 / -d.y());          // wall at y = -9
      if (!std::isfinite(t) || t > 60) continue;
      pts.push_back((d * (t + noise(rng))).cast<float>());
    }
  }
  return pts;
}

// Integrates the scans into both maps and compares them voxel by voxel.
void expect_same_as_octomap(const std::vector<std::vector<Vec3f>>& scans, const std::vector<Pose>& poses,
                            std::size_t min_voxels) {
  OccupancyParams p;  // OctoMap's defaults for hit, miss and clamping
  p.voxel_size = 0.25;
  p.min_point_range = 0.0;
  p.max_point_range = 25.0;  // OctoMap's maxrange: clear up to it, do not insert farther returns
  p.max_clearing_range = 25.0;
  OccupancyGrid grid(p);
  octomap::OcTree tree(p.voxel_size);
  tree.setProbHit(0.7);
  tree.setProbMiss(0.4);
  tree.setClampingThresMin(0.1192);
  tree.setClampingThresMax(0.971);

  for (std::size_t s = 0; s < scans.size(); ++s) {
    const Pose& T = poses[s];
    grid.integrate_scan(scans[s], T);
    octomap::Pointcloud cloud;
    for (const Vec3f& q : scans[s]) {
      const Vec3d w = T * q.cast<double>();
      cloud.push_back(static_cast<float>(w.x()), static_cast<float>(w.y()), static_cast<float>(w.z()));
    }
    const Vec3d o = T.translation();
    tree.insertPointCloud(cloud, octomap::point3d(o.x(), o.y(), o.z()), p.max_point_range);
  }

  std::size_t ours = 0, same = 0, occupied_mismatch = 0;
  for (const auto& [bk, block] : grid.blocks()) {
    for (int i = 0; i < kBlockVoxels; ++i) {
      const float lo = block->cells[i].log_odds;
      if (std::isnan(lo)) continue;
      ++ours;
      const Vec3d c = grid.center_of(voxel_of(bk, i));
      const octomap::OcTreeNode* n = tree.search(c.x(), c.y(), c.z());
      if (n && std::abs(n->getLogOdds() - lo) < 1e-4f) ++same;
      if (!n || tree.isNodeOccupied(n) != block->occupied(i)) ++occupied_mismatch;
    }
  }
  std::size_t theirs = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    theirs += static_cast<std::size_t>(1) << (3 * (tree.getTreeDepth() - it.getDepth()));
  std::printf("same log-odds: %zu of %zu voxels (%.3f%%), occupied mismatch %.3f%%, OctoMap/ours %.4f\n", same, ours,
              100.0 * same / ours, 100.0 * occupied_mismatch / grid.num_occupied_voxels(),
              static_cast<double>(theirs) / ours);
  ASSERT_GT(ours, min_voxels);
  // Both trace rays with their own DDA, ours with fixed-point crossing parameters
  // (occupancy_raycast.hpp); they may differ only where a ray grazes a voxel edge or corner.
  EXPECT_GT(static_cast<double>(same) / ours, 0.995) << same << " of " << ours;
  EXPECT_LT(static_cast<double>(occupied_mismatch) / grid.num_occupied_voxels(), 0.01);
  EXPECT_NEAR(static_cast<double>(theirs) / ours, 1.0, 0.005);
}

std::vector<Pose> drive_poses(int n) {
  std::vector<Pose> poses;
  for (int s = 0; s < n; ++s) {
    Pose T = Pose::Identity();
    T.linear() = Eigen::AngleAxisd(0.1 * s, Vec3d::UnitZ()).toRotationMatrix();
    T.translation() = Vec3d(1.3 * s + 0.11, 0.4 * s + 0.07, 0.03);
    poses.push_back(T);
  }
  return poses;
}

TEST(OccupancyVsOctoMap, SameLogOddsVoxelByVoxel) {
  std::mt19937 rng(3);
  std::vector<std::vector<Vec3f>> scans;
  for (int s = 0; s < 4; ++s) scans.push_back(ring_scan(rng, 512));
  expect_same_as_octomap(scans, drive_poses(4), 50000);
}

// A full 2048-column scan (as the benchmark's): rays close together, cast eight at a time.
TEST(OccupancyVsOctoMap, SameLogOddsVoxelByVoxelDenseScan) {
  std::mt19937 rng(5);
  std::vector<std::vector<Vec3f>> scans;
  for (int s = 0; s < 3; ++s) scans.push_back(ring_scan(rng, 2048));
  expect_same_as_octomap(scans, drive_poses(3), 50000);
}

// The real RELLIS-3D scan (vegetation, uneven ground), three times along a short drive.
TEST(OccupancyVsOctoMap, SameLogOddsVoxelByVoxelRealScan) {
  std::ifstream in(std::filesystem::path(SLAMVDB_SOURCE_DIR) / "../shared/fixtures/rellis3d-000104/000104.bin",
                   std::ios::binary);
  if (!in) GTEST_SKIP() << "no RELLIS-3D fixture in ../shared/fixtures";
  std::vector<Vec3f> scan;
  float v[4];
  while (in.read(reinterpret_cast<char*>(v), sizeof v))
    if (v[0] != 0 || v[1] != 0 || v[2] != 0) scan.emplace_back(v[0], v[1], v[2]);
  expect_same_as_octomap({scan, scan, scan}, drive_poses(3), 50000);
}

}  // namespace
}  // namespace slamvdb
