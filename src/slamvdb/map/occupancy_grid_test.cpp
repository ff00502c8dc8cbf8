#include "slamvdb/map/occupancy_grid.hpp"

#include <gtest/gtest.h>

#include <map>
#include <random>

#include <tbb/task_arena.h>
#include <set>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

using KeySet = std::set<std::tuple<int, int, int>>;
template <class Key>
std::tuple<int, int, int> tup(const Key& k) { return {k.x(), k.y(), k.z()}; }

// Brute force: every voxel in the bounding box whose cube the segment crosses with positive length.
KeySet brute_force_voxels(const Vec3d& a, const Vec3d& b) {
  KeySet out;
  const Vec3d lo = a.cwiseMin(b), hi = a.cwiseMax(b), d = b - a;
  for (int x = static_cast<int>(std::floor(lo.x())); x <= static_cast<int>(std::floor(hi.x())); ++x)
    for (int y = static_cast<int>(std::floor(lo.y())); y <= static_cast<int>(std::floor(hi.y())); ++y)
      for (int z = static_cast<int>(std::floor(lo.z())); z <= static_cast<int>(std::floor(hi.z())); ++z) {
        double t0 = 0, t1 = 1;
        const int c[3] = {x, y, z};
        for (int ax = 0; ax < 3; ++ax) {
          if (d[ax] == 0) {
            if (a[ax] < c[ax] || a[ax] >= c[ax] + 1) t0 = 2;
            continue;
          }
          double ta = (c[ax] - a[ax]) / d[ax], tb = (c[ax] + 1 - a[ax]) / d[ax];
          if (ta > tb) std::swap(ta, tb);
          t0 = std::max(t0, ta), t1 = std::min(t1, tb);
        }
        if (t1 - t0 > 1e-9) out.insert({x, y, z});
      }
  return out;
}

TEST(TraverseVoxels, MatchesBruteForceOnRandomSegments) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-20.0, 20.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec3d a(u(rng), u(rng), u(rng) * 0.3), b(u(rng), u(rng), u(rng) * 0.3);
    KeySet dda;
    traverse_voxels(a, b, [&](const VoxelKey& k) { EXPECT_TRUE(dda.insert(tup(k)).second) << "voxel visited twice"; });
    dda.insert({static_cast<int>(std::floor(b.x())), static_cast<int>(std::floor(b.y())),
                static_cast<int>(std::floor(b.z()))});
    ASSERT_EQ(dda, brute_force_voxels(a, b)) << "trial " << trial;
  }
}

TEST(TraverseVoxels, AxisAlignedAndDegenerate) {
  int n = 0;
  traverse_voxels(Vec3d(0.5, 0.5, 0.5), Vec3d(10.5, 0.5, 0.5), [&](const VoxelKey& k) {
    EXPECT_EQ(k, VoxelKey(n, 0, 0));
    ++n;
  });
  EXPECT_EQ(n, 10);
  n = 0;
  traverse_voxels(Vec3d(0.2, 0.2, 0.2), Vec3d(0.7, 0.7, 0.7), [&](const VoxelKey&) { ++n; });
  EXPECT_EQ(n, 0);  // same voxel: the end voxel is never a miss
}

OccupancyParams test_params() {
  OccupancyParams p;
  p.voxel_size = 1.0;
  p.max_clearing_range = 100.0;
  p.min_point_range = 0.0;
  return p;
}

TEST(OccupancyGrid, LogOddsHitMissAndClamping) {
  OccupancyGrid grid(test_params());
  const std::vector<Vec3f> scan = {Vec3f(5.5f, 0.5f, 0.5f)};
  const Pose origin = Pose(Eigen::Translation3d(0.5, 0.5, 0.5));
  grid.integrate_scan(scan, origin);
  EXPECT_FLOAT_EQ(*grid.log_odds({6, 1, 1}), grid.params().log_odds_hit);
  for (int x = 0; x < 6; ++x) EXPECT_FLOAT_EQ(*grid.log_odds({x, 0, 0}), grid.params().log_odds_miss) << x;
  EXPECT_FALSE(grid.log_odds({7, 1, 1}).has_value());
  EXPECT_TRUE(grid.is_occupied({6, 1, 1}));
  for (int i = 0; i < 20; ++i) grid.integrate_scan(scan, origin);
  EXPECT_FLOAT_EQ(*grid.log_odds({6, 1, 1}), grid.params().clamp_max);
  EXPECT_FLOAT_EQ(*grid.log_odds({2, 0, 0}), grid.params().clamp_min);
}

TEST(OccupancyGrid, OneUpdatePerVoxelPerScanAndHitsWin) {
  OccupancyGrid grid(test_params());
  // Point A ends in voxel 3; point B's ray crosses voxel 3 on its way to voxel 8. Ten copies of A.
  std::vector<Vec3f> scan(10, Vec3f(3.5f, 0.5f, 0.5f));
  scan.push_back(Vec3f(8.5f, 0.5f, 0.5f));
  const auto stats = grid.integrate_scan(scan, Pose::Identity());
  EXPECT_FLOAT_EQ(*grid.log_odds({3, 0, 0}), grid.params().log_odds_hit);  // once, and as a hit
  EXPECT_FLOAT_EQ(*grid.log_odds({1, 0, 0}), grid.params().log_odds_miss); // once, not 11 times
  EXPECT_EQ(stats.hit_updates, 2u);
  EXPECT_EQ(stats.miss_updates, 7u);  // voxels 0,1,2,4,5,6,7
}

TEST(OccupancyGrid, InvalidPointsAreDroppedAndCounted) {
  OccupancyParams p = test_params();
  p.min_point_range = 1.0;
  p.max_point_range = 50.0;
  OccupancyGrid grid(p);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const std::vector<Vec3f> scan = {Vec3f(nan, 0, 0), Vec3f(0, inf, 0), Vec3f::Zero(), Vec3f(0.5f, 0, 0),
                                   Vec3f(80, 0, 0), Vec3f(10, 0, 0)};
  const auto s = grid.integrate_scan(scan, Pose::Identity());
  EXPECT_EQ(s.points, 6u);
  EXPECT_EQ(s.dropped_nonfinite, 2u);
  EXPECT_EQ(s.dropped_no_return, 1u);
  EXPECT_EQ(s.dropped_too_close, 1u);
  EXPECT_EQ(s.beyond_max_range, 1u);
  EXPECT_EQ(s.hit_updates, 1u);
  EXPECT_FALSE(grid.is_occupied({80, 0, 0}));  // beyond max range: cleared up to 50 m, not inserted
  EXPECT_TRUE(grid.log_odds({45, 0, 0}).has_value());
  EXPECT_FALSE(grid.log_odds({55, 0, 0}).has_value());
}

TEST(OccupancyGrid, ClearingRangeLimitsMisses) {
  OccupancyParams p = test_params();
  p.max_clearing_range = 5.0;
  OccupancyGrid grid(p);
  grid.integrate_scan({Vec3f(20.5f, 0.5f, 0.5f)}, Pose::Identity());
  EXPECT_TRUE(grid.log_odds({3, 0, 0}).has_value());
  EXPECT_FALSE(grid.log_odds({10, 0, 0}).has_value());
  EXPECT_TRUE(grid.is_occupied({20, 0, 0}));
}

TEST(OccupancyGrid, FreedVoxelsAreReported) {
  OccupancyGrid grid(test_params());
  grid.integrate_scan({Vec3f(5.5f, 0.5f, 0.5f)}, Pose::Identity());
  std::vector<VoxelKey> freed;
  for (int i = 0; i < 5 && freed.empty(); ++i) grid.integrate_scan({Vec3f(9.5f, 0.5f, 0.5f)}, Pose::Identity(), &freed);
  ASSERT_EQ(freed.size(), 1u);
  EXPECT_EQ(freed[0], VoxelKey(5, 0, 0));
  EXPECT_FALSE(grid.is_occupied({5, 0, 0}));
  EXPECT_EQ(grid.num_occupied_voxels(), 1u);
}

TEST(OccupancyGrid, WorksTensOfKilometresFromTheOrigin) {
  OccupancyParams p;  // 0.25 m voxels
  OccupancyGrid grid(p);
  Pose T = Pose::Identity();
  T.translation() = Vec3d(-42000.3, 37000.7, 120.1);
  grid.integrate_scan({Vec3f(10.0f, 2.0f, -1.0f)}, T);
  const Vec3d hit = T * Vec3d(10.0, 2.0, -1.0);
  EXPECT_TRUE(grid.is_occupied(grid.key_of(hit)));
  EXPECT_LT((grid.center_of(grid.key_of(hit)) - hit).cwiseAbs().maxCoeff(), 0.125 + 1e-9);
  EXPECT_TRUE(grid.log_odds(grid.key_of(T * Vec3d(5.0, 1.0, -0.5))).has_value());
}

TEST(OccupancyGrid, BlockIndexingRoundTripsForNegativeKeys) {
  for (const VoxelKey& k : {VoxelKey(-1, -8, -9), VoxelKey(7, 8, -17), VoxelKey(-100000, 3, 99999)}) {
    EXPECT_EQ(voxel_of(block_of(k), index_in_block(k)), k);
  }
}

TEST(OccupancyGrid, NeighbourhoodQueryFindsNearBlocksOnly) {
  OccupancyGrid grid;  // 0.25 m voxels: 2 m blocks, 16 m regions
  const Vec3d near(3.0, -2.0, 0.5), far(5000.0, 0.0, 0.0), edge(-39.0, 0.0, 0.0);
  for (const Vec3d& p : {near, far, edge}) grid.set_log_odds(grid.key_of(p), 1.0f);
  std::set<std::tuple<int, int, int>> seen;
  grid.for_each_block_near(Vec3d::Zero(), 40.0, [&](const BlockKey& bk, const OccupancyGrid::Block& b) {
    EXPECT_EQ(b.num_occupied, 1);
    seen.insert(tup(bk));
  });
  EXPECT_EQ(seen.size(), 2u);
  EXPECT_TRUE(seen.count(tup(block_of(grid.key_of(near)))));
  EXPECT_TRUE(seen.count(tup(block_of(grid.key_of(edge)))));
}

TEST(OccupancyGrid, RejectsInvalidParameters) {
  OccupancyParams p;
  p.voxel_size = 0;
  EXPECT_THROW(OccupancyGrid{p}, Error);
  p = {};
  p.clamp_min = 1.0f;
  EXPECT_THROW(OccupancyGrid{p}, Error);
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// Rays are cast on many threads; a voxel's update must not depend on which thread got there
// first. Three overlapping scans integrated with 1 and with 8 worker threads (more than the cores,
// so that threads interleave) give the same log-odds in every voxel, and the same free list.
TEST(OccupancyGrid, OneAndManyThreadsGiveIdenticalVoxels) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<float> angle(-3.14159f, 3.14159f), elevation(-0.4f, 0.3f), range(2.f, 40.f);
  std::vector<std::vector<Vec3f>> scans(3);
  for (auto& scan : scans)
    for (int i = 0; i < 40000; ++i) {
      const float a = angle(rng), e = elevation(rng), r = range(rng);
      scan.emplace_back(r * std::cos(e) * std::cos(a), r * std::cos(e) * std::sin(a), r * std::sin(e));
    }
  auto integrate = [&](int threads) {
    OccupancyGrid grid;
    std::vector<VoxelKey> freed;
    tbb::task_arena arena(threads);
    arena.execute([&] {
      for (std::size_t s = 0; s < scans.size(); ++s) {
        Pose T = Pose::Identity();
        T.translation() = Vec3d(0.7 * s, 0.3 * s, 0.0);
        grid.integrate_scan(scans[s], T, &freed);
      }
    });
    std::map<std::tuple<int, int, int>, float> voxels;
    grid.for_each_known([&](const VoxelKey& k, float l) { voxels[tup(k)] = l; });
    std::set<std::tuple<int, int, int>> freed_set;
    for (const VoxelKey& k : freed) freed_set.insert(tup(k));
    return std::make_pair(voxels, freed_set);
  };
  const auto one = integrate(1), many = integrate(8);
  ASSERT_GT(one.first.size(), 100000u);
  EXPECT_EQ(one.first, many.first);
  EXPECT_EQ(one.second, many.second);
}

}  // namespace
}  // namespace slamvdb
