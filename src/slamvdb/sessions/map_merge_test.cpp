// Merging maps of sessions (map_merge.hpp) on the store tests' synthetic maps (two submaps each,
// random voxels, view counts up to UINT32_MAX): nothing is lost, sessions stay apart, and maps
// that cannot share a world are refused naming the difference.
#include "slamvdb/sessions/map_merge.hpp"

#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "slamvdb/testing/map_store_fixtures.hpp"

namespace slamvdb::sessions {
namespace {

using slamvdb::testing::make_map;

std::vector<SemanticMap> merge_test_maps(std::initializer_list<int> seeds) {
  std::vector<SemanticMap> maps;
  for (const int seed : seeds) maps.push_back(make_map(EmbeddingPrecision::kFloat16, 16, seed));
  return maps;
}

TEST(MergeSessionMaps, KeepsEverySubmapAndCountInItsSession) {
  std::vector<SemanticMap> inputs = merge_test_maps({1, 2});
  std::vector<std::vector<Pose>> anchors;
  for (const SemanticMap& m : inputs) {
    anchors.emplace_back();
    for (const SubmapInfo& s : m.submaps()) anchors.back().push_back(s.T_world_submap);
  }
  MapMergeReport report;
  const SemanticMap merged = merge_session_maps(inputs, {"monday", "friday"}, report);
  ASSERT_EQ(report.inputs.size(), 2u);
  EXPECT_EQ(report.merged.submaps, 4u);
  EXPECT_EQ(report.merged.observations, report.inputs[0].observations + report.inputs[1].observations);
  EXPECT_GT(report.inputs[1].observations, 0u);
  EXPECT_EQ(report.merged.semantic_voxels, report.inputs[0].semantic_voxels + report.inputs[1].semantic_voxels);
  EXPECT_EQ(report.merged.occupied_voxels, report.inputs[0].occupied_voxels + report.inputs[1].occupied_voxels);
  EXPECT_EQ(map_contents(merged).observations, report.merged.observations);
  EXPECT_EQ(inputs[0].num_submaps(), 0u) << "the inputs' submaps moved";
  ASSERT_EQ(merged.info().sessions.size(), 2u);
  EXPECT_EQ(merged.info().sessions[0].name, "monday");
  EXPECT_EQ(merged.info().sessions[1].name, "friday");
  EXPECT_EQ(merged.info().sessions[1].id, 1);
  // New ids in input order, each submap in its input's session, where it was in the world.
  const std::vector<SubmapInfo> submaps = merged.submaps();
  ASSERT_EQ(submaps.size(), 4u);
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(submaps[i].id, static_cast<int>(i));
    EXPECT_EQ(submaps[i].session, static_cast<int>(i / 2));
    EXPECT_EQ(submaps[i].T_world_submap.matrix(), anchors[i / 2][i % 2].matrix());
  }
}

// make_map picks its semantic voxels in hash order, which differs between two calls with one
// seed; this map is the same every time: one submap of `n` voxels, view counts 1..n.
SemanticMap merge_test_fixed_map(int n, double x) {
  MapParams params = make_map(EmbeddingPrecision::kFloat16, 16, 1).params();
  SemanticMap map(params, {.model_id = "simulated-clip-test", .source = "SIMULATED fixed map"});
  VoxelMap voxels(params);
  std::vector<float> e(16, 0.25f);
  for (int i = 0; i < n; ++i) {
    voxels.occupancy().set_log_odds({i, 2 * i, 1}, 2.0f);
    voxels.semantics().set({i, 2 * i, 1}, e.data(), static_cast<uint32_t>(i + 1));
  }
  SubmapInfo info;
  info.T_world_submap.translation() = Vec3d(x, 0, 0);
  map.add_finished_submap(info, std::move(voxels));
  return map;
}

TEST(MergeSessionMaps, IsAssociativeOnCounts) {
  // (A + B) + C and A + (B + C): the same sessions in the same order, the same counts.
  MapMergeReport report;
  std::vector<SemanticMap> ab, bc;
  ab.push_back(merge_test_fixed_map(100, 0.0)), ab.push_back(merge_test_fixed_map(200, 5.0));
  bc.push_back(merge_test_fixed_map(200, 5.0)), bc.push_back(merge_test_fixed_map(300, 10.0));
  std::vector<SemanticMap> left;
  left.push_back(merge_session_maps(ab, {"a", "b"}, report));
  left.push_back(merge_test_fixed_map(300, 10.0));
  const SemanticMap abc1 = merge_session_maps(left, {"ab", "c"}, report);
  std::vector<SemanticMap> right;
  right.push_back(merge_test_fixed_map(100, 0.0));
  right.push_back(merge_session_maps(bc, {"b", "c"}, report));
  const SemanticMap abc2 = merge_session_maps(right, {"a", "bc"}, report);
  const MapContents x = map_contents(abc1), y = map_contents(abc2);
  EXPECT_EQ(x.sessions, 3u);
  EXPECT_EQ(x.sessions, y.sessions);
  EXPECT_EQ(x.submaps, y.submaps);
  EXPECT_EQ(x.semantic_voxels, y.semantic_voxels);
  EXPECT_EQ(x.observations, y.observations);
  EXPECT_EQ(x.observations, 100u * 101 / 2 + 200u * 201 / 2 + 300u * 301 / 2);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(abc1.info().sessions[i].name, abc2.info().sessions[i].name);
}

TEST(MergeSessionMaps, RefusesMapsThatCannotShareAWorldNamingTheDifference) {
  const auto refusal = [](const std::function<void(MapParams&)>& change) {
    std::vector<SemanticMap> inputs = merge_test_maps({1});
    MapParams params = inputs[0].params();
    const MapInfo info = inputs[0].info();
    change(params);
    inputs.emplace_back(params, info);
    MapMergeReport report;
    try {
      merge_session_maps(inputs, {"a.svdb", "b.svdb"}, report);
    } catch (const Error& e) {
      EXPECT_EQ(inputs[0].num_submaps(), 2u) << "nothing moved";
      return std::string(e.what());
    }
    return std::string("merged");
  };
  EXPECT_EQ(refusal([](MapParams& p) { p.occupancy.voxel_size = 0.5; }),
            "cannot merge b.svdb with a.svdb: the maps have different voxel sizes: base 0.2 m, other 0.5 m");
  EXPECT_EQ(refusal([](MapParams& p) { p.occupancy.clamp_max = 2.0f; }),
            "cannot merge b.svdb with a.svdb: the maps have different occupancy settings: clamp max 3.25 and 2");
  std::vector<SemanticMap> one = merge_test_maps({1});
  MapMergeReport report;
  EXPECT_THROW(merge_session_maps(one, {"a"}, report), Error);
}

}  // namespace
}  // namespace slamvdb::sessions
