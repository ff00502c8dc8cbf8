// Merging overlapping submaps of different sessions (session_overlap_merge.hpp, through
// merge_session_maps): patches of ground on one grid, so that every merged voxel's expected count
// and count-weighted mean are known exactly.
#include "slamvdb/sessions/session_overlap_merge.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "slamvdb/sessions/map_merge.hpp"

namespace slamvdb::sessions {
namespace {

constexpr int kOverlapPatchDim = 8;
constexpr double kOverlapPatchVoxel = 0.2;

// What session `seed` saw at world voxel (x, y): its view count and its mean embedding.
uint32_t overlap_patch_count(int seed, int x, int y) { return static_cast<uint32_t>(1 + (3 * x + y + seed) % 5); }
std::vector<float> overlap_patch_embedding(int seed, int x, int y) {
  std::vector<float> e(kOverlapPatchDim);
  for (int d = 0; d < kOverlapPatchDim; ++d) e[d] = static_cast<float>(std::sin(1.3 * seed + 0.1 * x + 0.07 * y + d));
  return e;
}

// One map of one session: a submap per entry of `starts`, each a 40 x 20 patch of ground whose
// first column is world voxel column start (the anchor moved by whole voxels), log-odds 1 each.
SemanticMap overlap_patch_map(int seed, const std::vector<int>& starts, double t0 = 0) {
  MapParams params;
  params.occupancy.voxel_size = kOverlapPatchVoxel;
  params.semantic = {kOverlapPatchDim, EmbeddingPrecision::kFloat32};
  SemanticMap map(params, {.model_id = "simulated-clip-test", .source = "SIMULATED patches " + std::to_string(seed)});
  int id = 0;
  for (const int start : starts) {
    VoxelMap voxels(params);
    for (int x = 0; x < 40; ++x)
      for (int y = 0; y < 20; ++y) {
        voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
        voxels.semantics().set({x, y, 0}, overlap_patch_embedding(seed, start + x, y).data(),
                               overlap_patch_count(seed, start + x, y));
      }
    SubmapInfo info;
    info.id = id++;
    info.T_world_submap.translation() = Vec3d(start * kOverlapPatchVoxel, 0, 0);
    info.time_range = {t0, t0 + 5};
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

struct OverlapWorldVoxel {
  uint64_t count = 0;
  std::vector<float> mean;
  float log_odds = 0;
};

// Every occupied voxel of `map` by its world key; fails the test if a place is in two submaps.
std::map<VoxelKey, OverlapWorldVoxel> overlap_world_voxels(const SemanticMap& map) {
  std::map<VoxelKey, OverlapWorldVoxel> out;
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& s) {
      const SemanticLayer& layer = s.voxels().semantics();
      s.voxels().occupancy().for_each_occupied([&](const VoxelKey& k, float lo) {
        const Vec3d p_world = info.T_world_submap * center_of_key(k, kOverlapPatchVoxel);
        const auto key = key_of_point<VoxelKey>(p_world, 1 / kOverlapPatchVoxel);
        const auto [it, inserted] = out.try_emplace(key);
        EXPECT_TRUE(inserted) << "world voxel " << key.x() << "," << key.y() << " is in two submaps";
        it->second.log_odds = lo;
        if (const auto h = layer.find(k)) {
          it->second.count = layer.count_of(*h);
          it->second.mean.resize(kOverlapPatchDim);
          layer.read(*h, it->second.mean.data());
        }
      });
    });
  return out;
}

// The count-weighted mean of what the sessions `seeds` (patches starting at `starts`) saw.
void expect_overlap_patch_voxels(const std::map<VoxelKey, OverlapWorldVoxel>& world, const std::vector<int>& seeds,
                         const std::vector<int>& starts) {
  std::size_t places = 0;
  for (int x = -10; x < 100; ++x)
    for (int y = 0; y < 20; ++y) {
      uint64_t count = 0;
      std::vector<double> sum(kOverlapPatchDim, 0.0);
      int seen = 0;
      for (std::size_t i = 0; i < seeds.size(); ++i) {
        if (x < starts[i] || x >= starts[i] + 40) continue;
        const uint32_t n = overlap_patch_count(seeds[i], x, y);
        const std::vector<float> e = overlap_patch_embedding(seeds[i], x, y);
        for (int d = 0; d < kOverlapPatchDim; ++d) sum[d] += n * static_cast<double>(e[d]);
        count += n, ++seen;
      }
      const auto it = world.find(VoxelKey(x, y, 0));
      if (seen == 0) {
        EXPECT_EQ(it, world.end());
        continue;
      }
      ++places;
      ASSERT_NE(it, world.end()) << x << "," << y;
      EXPECT_EQ(it->second.count, count) << x << "," << y;
      EXPECT_FLOAT_EQ(it->second.log_odds, static_cast<float>(seen)) << x << "," << y;
      for (int d = 0; d < kOverlapPatchDim; ++d) EXPECT_NEAR(it->second.mean[d], sum[d] / count, 1e-5) << x << "," << y;
    }
  EXPECT_EQ(places, world.size());
}

TEST(MergeOverlappingSessions, TwoDrivesOverPartlyTheSamePlaceBecomeOneSubmapWithEveryVoxelOnce) {
  std::vector<SemanticMap> inputs;
  inputs.push_back(overlap_patch_map(1, {0}, 10.0));
  inputs.push_back(overlap_patch_map(2, {10}, 100.0));
  MapMergeReport report;
  const SemanticMap merged = merge_session_maps(inputs, {"monday", "friday"}, report);
  ASSERT_EQ(report.absorbed.size(), 1u);
  const SubmapAbsorption& a = report.absorbed[0];
  EXPECT_EQ(a.target_id, 0);
  EXPECT_EQ(a.source_id, 1);
  EXPECT_EQ(a.target_session, 0);
  EXPECT_EQ(a.source_session, 1);
  EXPECT_DOUBLE_EQ(a.overlap, 0.75);  // 30 of 40 columns
  EXPECT_EQ(a.occupied_voxels_removed, 600);
  EXPECT_EQ(a.observations_dropped_free + a.observations_clipped, 0u);
  ASSERT_EQ(merged.num_submaps(), 1u);
  EXPECT_EQ(report.merged.occupied_voxels, 1000u);
  EXPECT_EQ(report.merged.observations, report.inputs[0].observations + report.inputs[1].observations)
      << "no observation count lost";
  ASSERT_EQ(merged.info().sessions.size(), 2u) << "both drives stay listed";
  const SubmapInfo submap = merged.submaps()[0];
  EXPECT_EQ(submap.session, 0);
  EXPECT_EQ(submap.time_range.begin, 10.0);
  EXPECT_EQ(submap.time_range.end, 15.0) << "monday's times only";
  expect_overlap_patch_voxels(overlap_world_voxels(merged), {1, 2}, {0, 10});
}

TEST(MergeOverlappingSessions, IsAssociativeOnCountsAndMeans) {
  MapMergeReport report;
  std::vector<SemanticMap> ab, left, bc, right;
  ab.push_back(overlap_patch_map(1, {0})), ab.push_back(overlap_patch_map(2, {10}));
  left.push_back(merge_session_maps(ab, {"a", "b"}, report)), left.push_back(overlap_patch_map(3, {20}));
  const SemanticMap abc1 = merge_session_maps(left, {"ab", "c"}, report);
  const uint64_t observations = report.merged.observations;
  bc.push_back(overlap_patch_map(2, {10})), bc.push_back(overlap_patch_map(3, {20}));
  right.push_back(overlap_patch_map(1, {0})), right.push_back(merge_session_maps(bc, {"b", "c"}, report));
  const SemanticMap abc2 = merge_session_maps(right, {"a", "bc"}, report);
  EXPECT_EQ(report.merged.observations, observations);
  const std::map<VoxelKey, OverlapWorldVoxel> w1 = overlap_world_voxels(abc1), w2 = overlap_world_voxels(abc2);
  ASSERT_EQ(w1.size(), 1200u);
  ASSERT_EQ(w2.size(), w1.size());
  for (const auto& [key, v] : w1) {
    const OverlapWorldVoxel& u = w2.at(key);
    EXPECT_EQ(u.count, v.count);
    EXPECT_EQ(u.log_odds, v.log_odds);
    for (int d = 0; d < kOverlapPatchDim; ++d) EXPECT_NEAR(u.mean[d], v.mean[d], 1e-5);
  }
  expect_overlap_patch_voxels(w1, {1, 2, 3}, {0, 10, 20});
  expect_overlap_patch_voxels(w2, {1, 2, 3}, {0, 10, 20});
  EXPECT_EQ(abc1.num_submaps(), 1u);
  EXPECT_EQ(abc2.num_submaps(), 1u);
}

TEST(MergeOverlappingSessions, SubmapsThatOverlapTooLittleOrShareASessionStaySeparate) {
  const auto merged_submaps = [](std::vector<int> a_starts, int b_start, const OverlapMergeOptions& options) {
    std::vector<SemanticMap> inputs;
    inputs.push_back(overlap_patch_map(1, a_starts)), inputs.push_back(overlap_patch_map(2, {b_start}));
    MapMergeReport report;
    const SemanticMap merged = merge_session_maps(inputs, {"a", "b"}, report, options);
    EXPECT_EQ(report.merged.observations, report.inputs[0].observations + report.inputs[1].observations);
    EXPECT_EQ(report.absorbed.size() + merged.num_submaps(), report.inputs[0].submaps + report.inputs[1].submaps);
    return merged.num_submaps();
  };
  EXPECT_EQ(merged_submaps({0}, 35, {}), 2u) << "5 of 40 columns: 12.5% < 30%";
  EXPECT_EQ(merged_submaps({0}, 35, {.min_overlap = 0.1}), 1u);
  EXPECT_EQ(merged_submaps({0}, 10, {.enabled = false}), 2u);
  EXPECT_EQ(merged_submaps({0, 10}, 200, {}), 3u) << "one session's submaps are the loop closer's to merge";
  EXPECT_EQ(merged_submaps({0, 100}, 10, {}), 2u) << "b's submap goes into a's first, the one it overlaps";
}

}  // namespace
}  // namespace slamvdb::sessions
