// The live server's submap events over a real map with real merges: a submap a loop closure merged
// into another is reported `merged` with the submap that now holds its voxels (so the page drops
// its chunks instead of drawing them twice), a submap that left memory `unloaded`, and a submap
// that was unloaded, read back and merged between two looks is still reported merged. The page's
// side of it (viewer/src/live_changes.js) is checked in node.
#include "slamvdb/server/live_map_service.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <map>
#include <vector>

#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
namespace {

Pose sensor_at(double x) {
  Pose T = Pose::Identity();
  T.translation() = Vec3d(x, 0.0, 1.5);
  return T;
}

// A patch of ground 16 x 12 m seen from 1.5 m above it, in the sensor frame at x.
std::vector<Vec3f> ground_scan(double x) {
  std::vector<Vec3f> pts;
  for (double gx = -8; gx <= 8; gx += 0.2)
    for (double gy = -6; gy <= 6; gy += 0.2)
      pts.emplace_back(static_cast<float>(gx - x), static_cast<float>(gy), -1.49f);
  return pts;
}

// Five finished submaps, ids 0 to 4, each two scans of the same ground: any two overlap fully.
void build_five_submaps(SemanticMap& map) {
  for (int id = 0; id < 5; ++id) {
    map.start_submap(sensor_at(0));
    for (int i = 0; i < 2; ++i) map.integrate_scan(10.0 * id + i, ground_scan(i), sensor_at(i));
  }
  map.finish_active_submap();
}

// The one event the look just made (the service's counter rose by one).
// `all_submaps`: what the map's holder says of every submap (Mapper::submaps), if anything.
nlohmann::json look(LiveMapService& live, const SemanticMap& map,
                    std::function<std::vector<SubmapInfo>()> all_submaps = {}) {
  const std::uint64_t before = live.changes();
  // attach() looks at the map at once, as the refresher does at its rate: each call is one look,
  // so the test decides what changed between two looks.
  live.attach(map, std::move(all_submaps));
  const nlohmann::json events = live.changes_since(before);
  EXPECT_EQ(events.size(), 1u) << events.dump();
  if (!events.empty()) return events.back();
  const nlohmann::json none = nlohmann::json::array();  // no event: the expectations below say what was missed
  return {{"added", none}, {"moved", none}, {"grew", none}, {"merged", none}, {"unloaded", none}};
}

nlohmann::json merged(int id, int into) { return {{"id", id}, {"into", into}}; }

TEST(LiveMapEvents, MergedSubmapsNameTheirTargetAndUnloadedOnesAreToldApart) {
  MapParams params;
  params.semantic = {8, EmbeddingPrecision::kFloat16};
  params.submap_length = 0.0;
  SemanticMap map(params);
  build_five_submaps(map);
  ASSERT_EQ(map.num_submaps(), 5u);
  LiveMapService live("SIMULATED ground", 8, {.refresh_seconds = 3600.0});  // looks only when told

  const nlohmann::json first = look(live, map);
  EXPECT_EQ(first.at("added").size(), 5u);
  EXPECT_TRUE(first.at("merged").empty());
  EXPECT_TRUE(first.at("unloaded").empty());

  // A loop closure merges 0 into 1, then 1 into 2; submap 3 leaves memory (kept by its holder).
  ASSERT_TRUE(map.merge_submaps(1, 0).merged);
  ASSERT_TRUE(map.merge_submaps(2, 1).merged);
  EXPECT_EQ(map.merged_into(0), 1);
  EXPECT_EQ(map.merged_into(3), std::nullopt);
  auto [info3, voxels3] = map.remove_finished_submap(3);
  const nlohmann::json second = look(live, map);
  // Both went where the voxels are now: 2 (0's went through 1, which is gone too).
  EXPECT_EQ(second.at("merged"), nlohmann::json::array({merged(0, 2), merged(1, 2)})) << second.dump();
  EXPECT_EQ(second.at("unloaded"), nlohmann::json::array({3})) << second.dump();
  EXPECT_FALSE(second.contains("left"));
  EXPECT_TRUE(second.at("added").empty());

  // What the mapper does to merge a submap out of memory: reads it back, then merges; no look
  // between the two, so only the merge record says where 3 went.
  map.add_finished_submap(info3, std::move(voxels3));
  ASSERT_TRUE(map.merge_submaps(4, 3).merged);
  const nlohmann::json third = look(live, map);
  EXPECT_EQ(third.at("merged"), nlohmann::json::array({merged(3, 4)})) << third.dump();
  EXPECT_TRUE(third.at("unloaded").empty());
  EXPECT_TRUE(third.at("added").empty());

  // Unloaded, then read back without a merge: unloaded, then added again.
  auto [info4, voxels4] = map.remove_finished_submap(4);
  EXPECT_EQ(look(live, map).at("unloaded"), nlohmann::json::array({4}));
  map.add_finished_submap(info4, std::move(voxels4));
  const nlohmann::json back = look(live, map);
  ASSERT_EQ(back.at("added").size(), 1u);
  EXPECT_EQ(back.at("added")[0].at("id"), 4);
  EXPECT_TRUE(back.at("merged").empty());
  EXPECT_EQ(live.info().at("submaps_in_memory"), 2);  // 2 and 4
  live.detach();
}

Pose shifted(Pose T, double dx) {
  T.translation().x() += dx;
  return T;
}

// A loop correction moves submaps in memory and out of it alike (Mapper::correct_submaps moves
// those out of memory where they are kept): both are told `moved` with their new anchors, so that
// the page re-places what it drew of a submap out of memory too.
TEST(LiveMapEvents, CorrectionsOfSubmapsOutOfMemoryAreToldMoved) {
  MapParams params;
  params.semantic = {8, EmbeddingPrecision::kFloat16};
  params.submap_length = 0.0;
  SemanticMap map(params);
  build_five_submaps(map);
  LiveMapService live("SIMULATED ground", 8, {.refresh_seconds = 3600.0});  // looks only when told
  std::map<int, SubmapInfo> kept;  // what the holder keeps of the submaps out of memory (Mapper::unloaded_)
  const auto all_submaps = [&] {
    std::vector<SubmapInfo> all = map.submaps();
    for (const auto& [id, info] : kept) all.push_back(info);
    return all;
  };
  EXPECT_EQ(look(live, map, all_submaps).at("added").size(), 5u);
  auto [info3, voxels3] = map.remove_finished_submap(3);
  kept[3] = info3;
  EXPECT_EQ(look(live, map, all_submaps).at("unloaded"), nlohmann::json::array({3}));

  // The correction: 2 in memory and 3 out of it, 1 m along x.
  const Pose T2 = shifted(map.submap_info(2)->T_world_submap, 1.0), T3 = shifted(info3.T_world_submap, 1.0);
  map.set_submap_poses({{2, T2}});
  kept[3].T_world_submap = T3;
  const nlohmann::json corrected = look(live, map, all_submaps);
  ASSERT_EQ(corrected.at("moved").size(), 2u) << corrected.dump();
  EXPECT_EQ(corrected.at("moved")[0].at("id"), 2);
  const nlohmann::json& moved3 = corrected.at("moved")[1];
  EXPECT_EQ(moved3.at("id"), 3);
  EXPECT_EQ(moved3.at("T_world_submap")[0][3].get<double>(), T3.translation().x());
  EXPECT_EQ(moved3.at("translation")[0].get<double>(), T3.translation().x());
  EXPECT_TRUE(corrected.at("unloaded").empty());
  EXPECT_TRUE(corrected.at("added").empty());
  EXPECT_EQ(live.info().at("submaps_in_memory"), 4);  // 3 is not answered from, only placed

  // Read back at its new anchor: added (drawn anew), and no longer watched out of memory.
  info3.T_world_submap = T3;
  kept.erase(3);
  map.add_finished_submap(info3, std::move(voxels3));
  const nlohmann::json back = look(live, map, all_submaps);
  ASSERT_EQ(back.at("added").size(), 1u);
  EXPECT_EQ(back.at("added")[0].at("id"), 3);
  EXPECT_TRUE(back.at("moved").empty());
  live.detach();
}

// A stream that fell behind the events kept gets one `resync` that lists the submaps out of memory
// with their anchors: the page reloads the rest and keeps what it drew of these.
TEST(LiveMapEvents, ResyncListsTheSubmapsOutOfMemory) {
  MapParams params;
  params.semantic = {8, EmbeddingPrecision::kFloat16};
  params.submap_length = 0.0;
  SemanticMap map(params);
  build_five_submaps(map);
  LiveMapService live("SIMULATED ground", 8, {.refresh_seconds = 3600.0, .max_events = 1});
  look(live, map);
  auto [info1, voxels1] = map.remove_finished_submap(1);
  auto [info3, voxels3] = map.remove_finished_submap(3);
  look(live, map);
  map.add_finished_submap(info1, std::move(voxels1));  // back: not listed
  look(live, map);
  const nlohmann::json events = live.changes_since(0);
  ASSERT_EQ(events.size(), 1u) << events.dump();
  const nlohmann::json& resync = events[0];
  EXPECT_TRUE(resync.at("resync").get<bool>());
  EXPECT_EQ(resync.at("changes"), 3);
  EXPECT_EQ(resync.at("unloaded"), nlohmann::json::array({3})) << resync.dump();
  ASSERT_EQ(resync.at("moved").size(), 1u);
  EXPECT_EQ(resync.at("moved")[0].at("id"), 3);
  EXPECT_EQ(resync.at("moved")[0].at("translation")[0].get<double>(), info3.T_world_submap.translation().x());
  live.detach();
}

// The page's bookkeeping of these events, without a browser: a merged submap's chunks are replaced
// by its target's next fetch, an unloaded one's are kept and not fetched.
TEST(LiveMapEvents, PageReplacesMergedChunksAndKeepsUnloadedOnes) {
  if (testing::run_command("node --version", 30.0).exit_code != 0) GTEST_SKIP() << "node is missing";
  const std::filesystem::path script = std::filesystem::path(SLAMVDB_SOURCE_DIR) / "viewer/test/live_changes.mjs";
  const auto r = testing::run_command(fmt::format("exec node {}", testing::shell_quote(script.string())), 60.0);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("live_changes: ok"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace slamvdb
