// query --db with the summaries that prune (fleet/fleet_search.hpp) on a real PostgreSQL 15 +
// PostGIS server: the answer equals the pulled file's exactly, and the submaps whose embeddings
// point away from the query were skipped (the count reported), including with a threshold; a
// submap without a summary (a row of schema version 1) is always read.
#include <gtest/gtest.h>

#include "slamvdb/fleet/fleet_search.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::quote_path;
using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;

// SIMULATED: `submaps` square patches (20 x 20 voxels of 0.25 m) 20 m apart along x; patch i's
// embeddings lie near axis i % 4 (a small per-voxel tilt), so each patch's cap is narrow.
SemanticMap axis_patches(int submaps) {
  MapParams params;
  params.occupancy.voxel_size = 0.25;
  params.semantic.dim = 4;
  params.submap_length = 0;
  SemanticMap map(params, {.model_id = "fleet-search-space", .source = "SIMULATED axis patches"});
  for (int id = 0; id < submaps; ++id) {
    VoxelMap voxels(params);
    for (int x = 0; x < 20; ++x)
      for (int y = 0; y < 20; ++y) {
        voxels.occupancy().set_log_odds({x, y, 0}, 2.0f);
        float e[4] = {0.01f * static_cast<float>(x), 0.01f * static_cast<float>(y), 0.005f * static_cast<float>(x + y), 0.02f};
        e[id % 4] = 1.0f;
        if ((x + y) % 2 == 0) voxels.semantics().set({x, y, 0}, e, 1);
      }
    SubmapInfo info;
    info.id = id;
    info.T_world_submap.translation() = Vec3d(20.0 * id, 0, 0);
    info.path_length = 5;
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

struct FleetSearchFixture {
  slamvdb::testing::TempDir tmp;
  slamvdb::testing::PostgresServer& server = slamvdb::testing::shared_postgres_server();
  std::string db = slamvdb::testing::fresh_test_database(server);
  std::string cli = shell_quote(SLAMVDB_CLI_PATH) + " --quiet ";
  std::string url = shell_quote(server.url(db));
  std::filesystem::path vector = tmp.path / "axis0.npy", region = tmp.path / "region.svdb";
  const std::string box = " --bbox -1,-1,-1,200,10,2";

  FleetSearchFixture() {
    FleetDatabase(server.url(db)).push_map(axis_patches(8), {.session = "patches"});
    const float v[4] = {1.0f, 0.02f, 0.01f, 0.0f};
    write_npy_array(vector, v, {4});
    const auto pulled = run_command(cli + "pull --db " + url + box + " -o " + quote_path(region) + " 2>&1");
    EXPECT_EQ(pulled.exit_code, 0) << pulled.output;
  }
  // The answers on the pulled file and on the fleet (CSV text each) and the fleet run's output.
  struct Answers {
    std::string file, fleet, fleet_output;
  };
  Answers ask(const std::string& options) {
    const auto a_csv = tmp.path / "file.csv", b_csv = tmp.path / "fleet.csv";
    const auto a = run_command(cli + "query " + quote_path(region) + " --vector " + quote_path(vector) + box + options +
                               " -o " + quote_path(a_csv) + " 2>&1");
    const auto b = run_command(cli + "query --db " + url + " --vector " + quote_path(vector) + box + options + " -o " +
                               quote_path(b_csv) + " 2>&1");
    EXPECT_EQ(a.exit_code, 0) << a.output;
    EXPECT_EQ(b.exit_code, 0) << b.output;
    return {slamvdb::testing::read_text_file(a_csv), slamvdb::testing::read_text_file(b_csv), b.output};
  }
};

TEST(FleetSearch, TopKOnTheFleetEqualsThePulledFileAndSkipsSubmapsThatCannotEnterIt) {
  FleetSearchFixture f;
  EXPECT_EQ(slamvdb::testing::psql_value(f.server, "SELECT count(*) FROM slamvdb.submaps WHERE embedding_radius BETWEEN 0.01 AND 0.5 AND cardinality(embedding_centroid) = 4", f.db),
            "8");
  const auto top = f.ask(" --top-k 50");
  EXPECT_EQ(top.fleet, top.file);
  EXPECT_EQ(std::count(top.fleet.begin(), top.fleet.end(), '\n'), 51);  // header + 50
  // Patches 0 and 4 lie along the query's axis; the six others cannot reach its top 50.
  EXPECT_NE(top.fleet_output.find("fleet: 8 submaps in the region, 2 read, 6 skipped by their summaries (6 of 8 groups)"),
            std::string::npos)
      << top.fleet_output;

  // More answers than the aligned patches hold: every patch is needed, none skipped, same answer.
  const auto all = f.ask(" --top-k 1000");
  EXPECT_EQ(all.fleet, all.file);
  EXPECT_NE(all.fleet_output.find("8 read, 0 skipped"), std::string::npos) << all.fleet_output;

  // A threshold alone (no top-k) prunes the same way.
  const auto above = f.ask(" --top-k 0 --threshold 0.9");
  EXPECT_EQ(above.fleet, above.file);
  EXPECT_EQ(std::count(above.fleet.begin(), above.fleet.end(), '\n'), 401);  // the two aligned patches' 200 each
  EXPECT_NE(above.fleet_output.find("2 read, 6 skipped"), std::string::npos) << above.fleet_output;

  // Neither: every cell is an answer, every submap read (once).
  const auto every = f.ask(" --top-k 0");
  EXPECT_EQ(every.fleet, every.file);
  EXPECT_EQ(std::count(every.fleet.begin(), every.fleet.end(), '\n'), 1601);
  EXPECT_NE(every.fleet_output.find("8 read, 0 skipped"), std::string::npos) << every.fleet_output;
}

TEST(FleetSearch, ASubmapWithoutASummaryIsAlwaysReadAndGroupsShareABound) {
  FleetSearchFixture f;
  // Patch 1 as a version-1 row would be (no summary): it must be read, and the answer is the same.
  slamvdb::testing::psql_value(
      f.server, "UPDATE slamvdb.submaps SET embedding_radius = NULL, embedding_centroid = NULL WHERE submap = 1", f.db);
  FleetDatabase fleet(f.server.url(f.db));
  const Eigen::Vector4f q(1.0f, 0.02f, 0.01f, 0.0f);
  SearchOptions options;
  options.top_k = 50;
  PullRequest request;
  request.box_fleet = Eigen::AlignedBox3d(Vec3d(-1, -1, -1), Vec3d(200, 10, 2));
  const auto check = [&](std::size_t in_region, std::size_t groups, std::size_t scored) {
    const PrunedRegion pruned = pull_for_search(fleet, request, std::span<const float>(q.data(), 4), options);
    EXPECT_EQ(pruned.report.submaps_in_region, in_region);
    EXPECT_EQ(pruned.report.groups, groups);
    EXPECT_EQ(pruned.report.submaps_scored, scored);
    EXPECT_EQ(pruned.report.submaps_skipped, in_region - scored);
    EXPECT_EQ(pruned.map.num_submaps(), scored);
    const SemanticMap whole = fleet.pull_map(request);
    const auto expected = similarity_search(whole, std::span<const float>(q.data(), 4), options);
    const auto got = similarity_search(pruned.map, std::span<const float>(q.data(), 4), options);
    ASSERT_EQ(got.size(), expected.size());
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].cell, expected[i].cell) << i;
      EXPECT_EQ(got[i].score, expected[i].score) << i;
    }
  };
  check(8, 8, 3);  // patches 0 and 4 (aligned) and 1 (no summary)

  // A second session whose patch 2 (axis 2) lies on patch 0 (axis 0): the two may share index
  // cells (their mean scores neither patch's cosine), so they form one group whose bound encloses
  // both caps and is read whole; its patches 0 and 1 lie outside the region.
  Pose onto = Pose::Identity();
  onto.translation() = Vec3d(-40, 0, 0);
  fleet.push_map(axis_patches(3), {.session = "moved"});
  // Then corrected (the catalog rows rewritten, payloads and summaries kept).
  EXPECT_EQ(fleet.push_map(axis_patches(3), {.session = "moved", .T_fleet_session = onto}).anchors_moved, 3);
  check(9, 8, 4);

  // Pushing the session again gives patch 1 its summary back (its catalog row only) and then it
  // is skipped like the other off-axis patches.
  const PushReport again = fleet.push_map(axis_patches(8), {.session = "patches"});
  EXPECT_EQ(again.anchors_moved, 1);
  EXPECT_EQ(again.submaps_unchanged, 7);
  EXPECT_EQ(again.rows_written, 0u);
  check(9, 8, 3);
}

}  // namespace
}  // namespace slamvdb::fleet
