// `slamvdb push` and `slamvdb pull` end to end on a real PostgreSQL 15 + PostGIS server the test
// starts: a saved map pushed, pushed again (nothing written), refused with exit 1 naming the problem
// (a server that is not there: the URL shown without its password), usage errors with exit 2 before
// any work; a region pulled into a map file that loads, a damaged payload leaving no file.
#include <gtest/gtest.h>

#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/query/query_set.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/text_file.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"
#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::quote_path;
using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;

TEST(PushCommand, PushesAMapFileOnceAndAgainWritesNothing) {
  slamvdb::testing::TempDir tmp;
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string db = slamvdb::testing::fresh_test_database(server);
  const auto file = tmp.path / "monday.svdb";
  save_map(file, slamvdb::testing::make_map(EmbeddingPrecision::kFloat16, 8, 3));
  const std::string push = shell_quote(SLAMVDB_CLI_PATH) + " --quiet push " + quote_path(file) + " --db " +
                           shell_quote(server.url(db)) + " --robot husky-1";
  const auto first = run_command(push + " 2>&1");
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("as session 'monday' (new)"), std::string::npos) << first.output;
  EXPECT_NE(first.output.find("2 added, 0 unchanged"), std::string::npos) << first.output;
  const auto blocks = slamvdb::testing::psql_value(server, "SELECT sum(blocks) FROM slamvdb.submaps", db);
  EXPECT_EQ(slamvdb::testing::psql_value(server, "SELECT count(*) FROM slamvdb.occupancy", db), blocks);
  EXPECT_EQ(slamvdb::testing::psql_value(server, "SELECT string_agg(submap::text, ',' ORDER BY submap) FROM slamvdb.submaps", db),
            "-7,3");

  const auto again = run_command(push + " --json 2>&1");
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("\"submaps_unchanged\": 2"), std::string::npos) << again.output;
  EXPECT_NE(again.output.find("\"rows_written\": 0"), std::string::npos) << again.output;

  // A map at another voxel size is refused from its summary, before its voxels are read.
  MapParams coarse;
  coarse.occupancy.voxel_size = 0.5;
  coarse.semantic.dim = 8;
  const auto other = tmp.path / "coarse.svdb";
  save_map(other, SemanticMap(coarse, {.model_id = "simulated-clip-test"}));
  const auto refused = run_command(shell_quote(SLAMVDB_CLI_PATH) + " push " + quote_path(other) + " --db " +
                                   shell_quote(server.url(db)) + " 2>&1");
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_NE(refused.output.find("in 'voxel_size': the fleet has '0.2', the map '0.5'"), std::string::npos)
      << refused.output;
  EXPECT_EQ(slamvdb::testing::psql_value(server, "SELECT count(*) FROM slamvdb.sessions", db), "1");
}

TEST(PushCommand, ErrorsAreExitOneWithTheReasonAndUsageErrorsExitTwo) {
  slamvdb::testing::TempDir tmp;
  const auto file = tmp.path / "m.svdb";
  save_map(file, slamvdb::testing::make_map(EmbeddingPrecision::kFloat16, 8, 3));
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH) + " push " + quote_path(file);
  const std::string nowhere = "postgresql://robot:s3cret@/fleet?host=" + (tmp.path / "none").string();
  const auto down = run_command(cli + " --db " + shell_quote(nowhere) + " 2>&1");
  EXPECT_EQ(down.exit_code, 1) << down.output;
  EXPECT_NE(down.output.find("cannot connect to the fleet database postgresql://robot:***@"), std::string::npos)
      << down.output;
  EXPECT_EQ(down.output.find("s3cret"), std::string::npos) << down.output;
  EXPECT_EQ(run_command(cli + " 2>&1").exit_code, 2);  // no --db
  const auto pose = run_command(cli + " --db x --fleet-pose 1,2 2>&1");
  EXPECT_EQ(pose.exit_code, 2) << pose.output;
  EXPECT_NE(pose.output.find("--fleet-pose"), std::string::npos) << pose.output;
  EXPECT_EQ(run_command(shell_quote(SLAMVDB_CLI_PATH) + " push " + quote_path(tmp.path / "missing.svdb") + " --db x 2>&1").exit_code, 2);
}

TEST(PullCommand, WritesARegionAsAMapFileThatLoadsAndWritesNothingOnADamagedPayload) {
  slamvdb::testing::TempDir tmp;
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string db = slamvdb::testing::fresh_test_database(server);
  const SemanticMap monday = slamvdb::testing::patch_map(3, 40);
  Pose north = Pose::Identity();
  north.translation() = Vec3d(0, 50, 0);
  FleetDatabase fleet(server.url(db));
  fleet.push_map(monday, {.session = "monday"});
  fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "tuesday", .T_fleet_session = north});
  const std::string pull = shell_quote(SLAMVDB_CLI_PATH) + " --quiet pull --db " + shell_quote(server.url(db));

  const auto region = tmp.path / "region.svdb";
  const auto both = run_command(pull + " --bbox 95,-5,-1,140,60,2 -o " + quote_path(region) + " 2>&1");
  ASSERT_EQ(both.exit_code, 0) << both.output;
  EXPECT_NE(both.output.find("pulled     2 submaps of 2 sessions (monday, tuesday)"), std::string::npos) << both.output;
  const SemanticMap back = load_map(region);
  ASSERT_EQ(back.num_submaps(), 2u);
  EXPECT_EQ(back.num_semantic_voxels(), 2 * 800u);
  EXPECT_EQ(back.info().model_id, "fleet-test-space");
  EXPECT_NE(back.info().source.find("fleet map"), std::string::npos) << back.info().source;
  EXPECT_TRUE(back.submap_info(1)->T_world_submap.translation().isApprox(Vec3d(100, 50, 0)));  // tuesday's, moved north
  std::size_t monday_occupied = 0;
  monday.read_submap(1, [&](const Submap& s) { monday_occupied = s.voxels().occupancy().num_occupied_voxels(); });
  back.read_submap(0, [&](const Submap& s) { EXPECT_EQ(s.voxels().occupancy().num_occupied_voxels(), monday_occupied); });
  // The file lists the fleet's sessions, each submap in its own (the pulled file is a normal multi-session map).
  ASSERT_EQ(back.info().sessions.size(), 2u);
  EXPECT_EQ(back.info().sessions[0].name, "monday");
  EXPECT_EQ(back.info().sessions[1].name, "tuesday");
  EXPECT_EQ(back.submap_info(0)->session, back.info().sessions[0].id);
  EXPECT_EQ(back.submap_info(1)->session, back.info().sessions[1].id);

  const auto one = run_command(pull + " --near 100,50 --radius 3 --session tuesday -o " + quote_path(region) + " 2>&1");
  ASSERT_EQ(one.exit_code, 0) << one.output;
  EXPECT_EQ(load_map(region).num_submaps(), 1u);

  slamvdb::testing::psql_value(server, "UPDATE slamvdb.semantics SET counts = set_byte(counts, 0, 7) WHERE submap = 2", db);
  const auto damaged_file = tmp.path / "damaged.svdb";
  const auto damaged = run_command(pull + " --bbox -10,-10,-1,300,10,2 -o " + quote_path(damaged_file) + " 2>&1");
  EXPECT_EQ(damaged.exit_code, 1) << damaged.output;
  EXPECT_NE(damaged.output.find("session 'monday' submap 2: CRC mismatch in semantic chunk 0"), std::string::npos)
      << damaged.output;
  EXPECT_FALSE(std::filesystem::exists(damaged_file));

  EXPECT_EQ(run_command(pull + " -o " + quote_path(region) + " 2>&1").exit_code, 2);  // no region
  EXPECT_EQ(run_command(pull + " --bbox 1,2,3 -o " + quote_path(region) + " 2>&1").exit_code, 2);
}

TEST(FleetQuery, QueryAndClassifyOnTheFleetAnswerAsOnThePulledFile) {
  slamvdb::testing::TempDir tmp;
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string db = slamvdb::testing::fresh_test_database(server);
  Pose north = Pose::Identity();
  north.translation() = Vec3d(3, 4, 0);  // overlapping the first session: cells shared across sessions
  FleetDatabase fleet(server.url(db));
  fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "monday"});
  fleet.push_map(slamvdb::testing::patch_map(3, 40), {.session = "tuesday", .T_fleet_session = north});
  const float v[4] = {1.0f, 0.05f, 0.02f, 0.1f};
  const auto vector = tmp.path / "v.npy";
  write_npy_array(vector, v, {4});
  QuerySet q;
  q.model_id = "fleet-test-space";
  q.names = {"near-edge", "far-edge"};
  q.vectors = QueryMatrix::Zero(2, 4);
  q.vectors(0, 3) = 1;
  q.vectors(1, 1) = 1;
  const auto queries = tmp.path / "q.json";
  save_query_set(queries, q);
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH) + " --quiet ";
  const std::string url = shell_quote(server.url(db)), box = " --bbox 95,-5,-1,140,20,2";
  const auto region = tmp.path / "region.svdb";
  ASSERT_EQ(run_command(cli + "pull --db " + url + box + " -o " + quote_path(region)).exit_code, 0);

  const auto file_q = tmp.path / "file_q.csv", fleet_q = tmp.path / "fleet_q.csv";
  const auto a = run_command(cli + "query " + quote_path(region) + " --vector " + quote_path(vector) + box +
                             " --top-k 500 -o " + quote_path(file_q) + " 2>&1");
  const auto b = run_command(cli + "query --db " + url + " --vector " + quote_path(vector) + box +
                             " --top-k 500 -o " + quote_path(fleet_q) + " 2>&1");
  ASSERT_EQ(a.exit_code, 0) << a.output;
  ASSERT_EQ(b.exit_code, 0) << b.output;
  const std::string answers = slamvdb::testing::read_text_file(fleet_q);
  EXPECT_EQ(answers, slamvdb::testing::read_text_file(file_q));
  EXPECT_GT(std::count(answers.begin(), answers.end(), '\n'), 400);

  const auto file_c = tmp.path / "file_c.csv", fleet_c = tmp.path / "fleet_c.csv";
  const auto c = run_command(cli + "classify " + quote_path(region) + " --queries " + quote_path(queries) + box +
                             " -o " + quote_path(file_c) + " 2>&1");
  const auto d = run_command(cli + "classify --db " + url + " --session monday --session tuesday --queries " +
                             quote_path(queries) + box + " -o " + quote_path(fleet_c) + " 2>&1");
  ASSERT_EQ(c.exit_code, 0) << c.output;
  ASSERT_EQ(d.exit_code, 0) << d.output;
  // The file's CSV ends with last_session (the newest session that saw the voxel, issue 23); the
  // fleet stores no per-voxel session yet, so classify --db by tiles writes the columns before it.
  std::string file_rows = slamvdb::testing::read_text_file(file_c), without_last;
  for (std::size_t at = 0; at < file_rows.size();) {
    const std::size_t end = file_rows.find('\n', at);
    const std::string line = file_rows.substr(at, end - at);
    without_last += line.substr(0, line.rfind(',')) + "\n";
    at = end == std::string::npos ? file_rows.size() : end + 1;
  }
  EXPECT_NE(file_rows.find(",last_session\n"), std::string::npos);
  EXPECT_EQ(slamvdb::testing::read_text_file(fleet_c), without_last);

  const auto no_region = run_command(cli + "query --db " + url + " --vector " + quote_path(vector) + " 2>&1");
  EXPECT_EQ(no_region.exit_code, 2) << no_region.output;
  EXPECT_NE(no_region.output.find("--db needs a region"), std::string::npos) << no_region.output;
  EXPECT_EQ(run_command(cli + "query " + quote_path(region) + " --db " + url + box + " --vector " + quote_path(vector)).exit_code, 2);
  // On a map file --session restricts to the file's sessions (issue 23); a name it lacks is refused.
  const auto unknown = run_command(cli + "classify " + quote_path(region) + " --session sunday --queries " +
                                   quote_path(queries) + " 2>&1");
  EXPECT_EQ(unknown.exit_code, 1) << unknown.output;
  EXPECT_NE(unknown.output.find("no session 'sunday'"), std::string::npos) << unknown.output;
}

}  // namespace
}  // namespace slamvdb::fleet
