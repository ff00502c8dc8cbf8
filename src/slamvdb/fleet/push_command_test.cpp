// `slamvdb push` end to end on a real PostgreSQL 15 + PostGIS server the test starts: a saved map
// pushed, pushed again (nothing written), refused with exit 1 naming the problem (a server that
// is not there: the URL shown without its password), usage errors with exit 2 before any work.
#include <gtest/gtest.h>

#include "slamvdb/store/map_store.hpp"
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

}  // namespace
}  // namespace slamvdb::fleet
