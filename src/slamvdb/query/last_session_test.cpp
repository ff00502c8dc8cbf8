// A voxel's last-observed session (issue 23) from fusion to answer: two drives over partly the
// same ground merged into one map (sessions/map_merge.hpp), the newer drive winning per voxel,
// then read back through the global index (query_points, classify_map) and used to keep what one
// drive saw last (sessions::keep_last_observed, `export --last-session`).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "slamvdb/query/map_query.hpp"
#include "slamvdb/sessions/map_merge.hpp"
#include "slamvdb/sessions/session_selection.hpp"

namespace slamvdb {
namespace {

constexpr int kLastSessionDim = 4;
constexpr double kLastSessionVoxel = 0.5;

// One drive's map: one submap, a 20 x 10 patch of ground from world voxel column `start`, seen
// between t0 and t0 + 5 s.
SemanticMap last_session_drive(int start, double t0) {
  MapParams params;
  params.occupancy.voxel_size = kLastSessionVoxel;
  params.semantic = {kLastSessionDim, EmbeddingPrecision::kFloat32};
  SemanticMap map(params, {.model_id = "simulated-clip-test", .source = "SIMULATED patch"});
  VoxelMap voxels(params);
  const std::vector<float> e(kLastSessionDim, 1.0f);
  for (int x = 0; x < 20; ++x)
    for (int y = 0; y < 10; ++y) {
      voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
      voxels.semantics().set({x, y, 0}, e.data(), 2);
    }
  SubmapInfo info;
  info.T_world_submap.translation() = Vec3d(start * kLastSessionVoxel, 0, 0);
  info.time_range = {t0, t0 + 5};
  map.add_finished_submap(info, std::move(voxels));
  return map;
}

Vec3d last_session_point(int x) { return {(x + 0.5) * kLastSessionVoxel, 2.25, 0.25}; }

// Monday covers columns 0..19, Friday 5..24; `friday_first` lists Friday as the first input (its
// submap is the one the other is merged into, and it gets session id 0).
SemanticMap merged_drives(bool friday_first) {
  std::vector<SemanticMap> inputs;
  inputs.push_back(friday_first ? last_session_drive(5, 1000.0) : last_session_drive(0, 10.0));
  inputs.push_back(friday_first ? last_session_drive(0, 10.0) : last_session_drive(5, 1000.0));
  sessions::MapMergeReport report;
  SemanticMap merged = sessions::merge_session_maps(
      inputs, friday_first ? std::vector<std::string>{"friday", "monday"} : std::vector<std::string>{"monday", "friday"},
      report);
  EXPECT_EQ(report.absorbed.size(), 1u) << "the drives overlap by 15 of 20 columns";
  return merged;
}

TEST(LastObservedSession, TheNewerDriveWinsEveryVoxelItSawWhicheverInputItWas) {
  for (const bool friday_first : {false, true}) {
    const SemanticMap map = merged_drives(friday_first);
    ASSERT_EQ(map.num_submaps(), 1u);
    const std::vector<Vec3d> points = {last_session_point(2), last_session_point(10), last_session_point(22),
                                       last_session_point(40)};
    const std::vector<PointQuery> answers = query_points(map, points);
    ASSERT_TRUE(answers[0].found && answers[1].found && answers[2].found);
    EXPECT_EQ(answers[0].last_session_name, "monday") << "only Monday saw it";
    EXPECT_EQ(answers[1].last_session_name, "friday") << "both saw it; Friday is newer (friday first: " << friday_first << ")";
    EXPECT_EQ(answers[2].last_session_name, "friday") << "only Friday saw it";
    EXPECT_FALSE(answers[3].found);
    EXPECT_EQ(answers[3].last_session_name, "");

    // classify_map says the same of every cell.
    QuerySet queries;
    queries.model_id = "simulated-clip-test";
    queries.names = {"ground"};
    queries.vectors = QueryMatrix::Ones(1, kLastSessionDim);
    std::size_t by_friday = 0;
    for (const ClassifiedCell& c : classify_map(map, queries)) {
      const std::string name = session_name(map.info().sessions, c.last_session);
      const double x = c.position_world.x() / kLastSessionVoxel;
      EXPECT_EQ(name, x < 5 ? "monday" : "friday") << x;
      by_friday += name == "friday";
    }
    EXPECT_EQ(by_friday, 20u * 10u);
  }
}

TEST(LastObservedSession, KeepsWhatOneDriveSawLast) {
  SemanticMap map = merged_drives(false);
  EXPECT_THROW(sessions::keep_last_observed(map, {"sunday"}), Error);
  EXPECT_EQ(map.num_semantic_voxels(), 25u * 10u) << "a refused name changes nothing";
  const sessions::LastObservedSelection kept = sessions::keep_last_observed(map, {"monday"});
  EXPECT_EQ(kept.semantic_voxels_kept, 5u * 10u) << "the columns Friday did not see again";
  EXPECT_EQ(kept.semantic_voxels_removed, 20u * 10u);
  EXPECT_EQ(map.num_semantic_voxels(), 5u * 10u);
  EXPECT_EQ(map.num_occupied_voxels(), 25u * 10u) << "the occupancy stays as context";
  EXPECT_FALSE(query_points(map, std::vector<Vec3d>{last_session_point(10)})[0].found);
}

}  // namespace
}  // namespace slamvdb
