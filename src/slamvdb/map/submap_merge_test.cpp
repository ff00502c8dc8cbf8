// combine_occupancy (the world occupancy behind `info --check`, export, nav grids and the map
// comparisons) against the rule written out plainly: every known voxel's centre moved by its
// submap's pose into the world grid, one map per submap holding the maximum of its voxels in each
// cell, then the clamped sum over the submaps in order. The fast path (an affine map of the key,
// one hash lookup per voxel) must give the same cells and bit for bit the same log-odds.
#include "slamvdb/map/submap_merge.hpp"

#include <absl/container/flat_hash_map.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>

namespace slamvdb::submap_merge_test {
namespace {

std::vector<WorldOccupancyCell> combine_occupancy_as_written(const std::vector<PlacedVoxelMap>& submaps,
                                                             double cell_size, const OccupancyParams& params) {
  absl::flat_hash_map<IndexCellKey, float> world;
  for (const PlacedVoxelMap& s : submaps) {
    absl::flat_hash_map<IndexCellKey, float> own;
    s.voxels->occupancy().for_each_known([&](const VoxelKey& k, float lo) {
      const Vec3d p = s.T_world_submap * center_of_key(k, s.voxels->voxel_size());
      if (!in_grid_extent(p * (1.0 / cell_size))) return;
      const auto [it, inserted] = own.try_emplace(key_of_point<IndexCellKey>(p, 1.0 / cell_size), lo);
      if (!inserted) it->second = std::max(it->second, lo);
    });
    for (const auto& [cell, lo] : own) {
      const auto [it, inserted] = world.try_emplace(cell, lo);
      if (!inserted) it->second = std::clamp(it->second + lo, params.clamp_min, params.clamp_max);
    }
  }
  std::vector<WorldOccupancyCell> out;
  for (const auto& [cell, lo] : world) out.push_back({cell, lo});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.cell < b.cell; });
  return out;
}

// A slab of known voxels around the submap origin with log-odds from the whole clamped range
// (occupied, free, exactly 0 and -0).
VoxelMap random_submap(std::mt19937& rng, double voxel_size) {
  MapParams params;
  params.occupancy.voxel_size = voxel_size;
  VoxelMap map(params);
  std::uniform_int_distribution<int> xy(-60, 60), z(-6, 6), pick(0, 9);
  std::uniform_real_distribution<float> lo(params.occupancy.clamp_min, params.occupancy.clamp_max);
  for (int i = 0; i < 20000; ++i) {
    const int p = pick(rng);
    map.occupancy().set_log_odds({xy(rng), xy(rng), z(rng)}, p == 0 ? 0.0f : p == 1 ? -0.0f : lo(rng));
  }
  return map;
}

Pose placed_at(double yaw, double pitch, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Vec3d::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3d::UnitY())).toRotationMatrix();
  T.translation() = t;
  return T;
}

void expect_identical(const std::vector<WorldOccupancyCell>& got, const std::vector<WorldOccupancyCell>& want) {
  ASSERT_EQ(got.size(), want.size());
  std::size_t differing = 0;
  for (std::size_t i = 0; i < got.size(); ++i)
    differing += got[i].cell != want[i].cell ||
                 std::bit_cast<uint32_t>(got[i].log_odds) != std::bit_cast<uint32_t>(want[i].log_odds);
  EXPECT_EQ(differing, 0u);
}

TEST(CombineOccupancy, RotatedAndTranslatedSubmapsGiveTheCellsOfTheRuleAsWritten) {
  std::mt19937 rng(7);
  std::vector<VoxelMap> maps;
  for (int i = 0; i < 6; ++i) maps.push_back(random_submap(rng, 0.25));
  // Overlapping submaps turned about two axes, at translations off and on the grid (0.125 m puts
  // every voxel centre of an unrotated submap exactly on a cell boundary: the exact fallback).
  const std::vector<Pose> poses = {placed_at(0.0, 0.0, Vec3d::Zero()),
                                   placed_at(0.0, 0.0, Vec3d(0.125, -0.125, 0.125)),
                                   placed_at(0.3, 0.0, Vec3d(2.1, -1.3, 0.2)),
                                   placed_at(M_PI / 2, 0.0, Vec3d(1.0, 0.5, 0.0)),
                                   placed_at(-2.2, 0.05, Vec3d(-3.7, 4.4, -0.6)),
                                   placed_at(1.1, -0.02, Vec3d(1.0e4 + 0.3, -2.5e3, 12.0))};
  std::vector<PlacedVoxelMap> placed;
  for (std::size_t i = 0; i < maps.size(); ++i) placed.push_back({&maps[i], poses[i]});
  const OccupancyParams params;
  for (const double cell_size : {0.25, 0.5, 0.3}) {
    SCOPED_TRACE(cell_size);
    const auto want = combine_occupancy_as_written(placed, cell_size, params);
    ASSERT_GT(want.size(), 20000u);
    expect_identical(combine_occupancy(placed, cell_size, params), want);
  }
  // Sums reach the clamps: the same submap placed again and again.
  std::vector<PlacedVoxelMap> stacked(5, placed[2]);
  expect_identical(combine_occupancy(stacked, 0.25, params), combine_occupancy_as_written(stacked, 0.25, params));
}

TEST(CombineOccupancy, SubmapsFarOutOrBeyondTheExtentAreResampledExactly) {
  std::mt19937 rng(11);
  VoxelMap near = random_submap(rng, 0.25), far = random_submap(rng, 0.25);
  // 5e5 m is beyond the affine form's extent at 0.25 m cells; 1e9 m beyond the grid itself (dropped).
  for (const double x : {5.0e5, 1.0e9}) {
    SCOPED_TRACE(x);
    const std::vector<PlacedVoxelMap> placed = {{&near, placed_at(0.4, 0.0, Vec3d::Zero())},
                                                {&far, placed_at(0.7, 0.0, Vec3d(x, 0.0, 0.0))}};
    expect_identical(combine_occupancy(placed, 0.25, OccupancyParams{}),
                     combine_occupancy_as_written(placed, 0.25, OccupancyParams{}));
  }
}

}  // namespace
}  // namespace slamvdb::submap_merge_test
