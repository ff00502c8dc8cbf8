// A fleet split across three real PostgreSQL 15 servers the test starts (a coordinator and two
// shards, joined by postgres_fdw): rows land on the shard of their tile, a region asks only the
// shards that hold it (seen in each shard's own statement log), the answers are those of the same
// pushes into one server, and a dead shard fails only the regions it holds, with exit 1, quickly.
#include <gtest/gtest.h>

#include <chrono>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/map_store_fixtures.hpp"
#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/postgres_shards.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::PostgresServer;
using slamvdb::testing::psql_value;
using slamvdb::testing::statements_in;

// Two shard servers for the suite, each logging every statement with its database's name.
struct ShardServers : slamvdb::testing::PostgresServerSet {
  ShardServers() : PostgresServerSet(2, "shard") {
    for (int i = 0; i < 2; ++i) slamvdb::testing::log_statements((*this)[i], true);
  }
};

PostgresServer& shard_server(int i) {
  static ShardServers servers;
  return servers[i];
}

class FleetShards : public ::testing::Test {
 protected:
  void SetUp() override {
    coordinator_ = slamvdb::testing::fresh_test_database(coordinator_server());
    for (int i = 0; i < 2; ++i) shard_db_[i] = slamvdb::testing::fresh_test_database(shard_server(i), "_shard");
  }
  static PostgresServer& coordinator_server() { return slamvdb::testing::shared_postgres_server(); }
  std::string url() const { return coordinator_server().url(coordinator_); }
  static Eigen::AlignedBox3d box(double x0, double x1) { return {Vec3d(x0, -50, -1e3), Vec3d(x1, 50, 1e3)}; }

  // Monday near the origin (tile 0), pushed when shard a is the only one; tuesday 2 km east
  // (tile 4), pushed after shard b joined: new tiles go to the newest shard.
  const SemanticMap monday_ = slamvdb::testing::patch_map(3, 16);
  const SemanticMap tuesday_ = slamvdb::testing::patch_map(3, 16);
  const Pose T_fleet_tuesday_ = slamvdb::testing::make_pose(0.0, {2000, 0, 0});
  // With `command`, shard b is added by `slamvdb add-shard`, as the README's procedure does.
  void push_sharded(FleetDatabase& fleet, bool command = false) {
    EXPECT_EQ(fleet.add_shard("a", shard_server(0).url(shard_db_[0])), 1);
    fleet.push_map(monday_, {.session = "monday"});
    if (command) {
      const auto added = slamvdb::testing::run_command(
          slamvdb::testing::shell_quote(SLAMVDB_CLI_PATH) + " add-shard --db " + slamvdb::testing::shell_quote(url()) +
          " --shard-db " + slamvdb::testing::shell_quote(shard_server(1).url(shard_db_[1])) + " --name b 2>&1");
      EXPECT_EQ(added.exit_code, 0) << added.output;
      EXPECT_NE(added.output.find("shard      'b' (id 2) added"), std::string::npos) << added.output;
    } else {
      EXPECT_EQ(fleet.add_shard("b", shard_server(1).url(shard_db_[1])), 2);
    }
    fleet.push_map(tuesday_, {.session = "tuesday", .T_fleet_session = T_fleet_tuesday_});
  }
  std::string shard_sql(int i, const std::string& query) const { return psql_value(shard_server(i), query, shard_db_[i]); }
  std::size_t statements(int i) const { return statements_in(shard_server(i), shard_db_[i]); }

  std::string coordinator_;
  std::string shard_db_[2];
};

// The region's submaps as one map (the pulled session and submap as the submap's time).
SemanticMap shards_region_of(const std::string& url, const Eigen::AlignedBox3d& region, const SemanticMap& like) {
  SemanticMap out(like.params(), like.info());
  FleetDatabase(url).pull({region}, [&](PulledSubmap&& s) { out.add_finished_submap(s.info, std::move(s.voxels)); });
  return out;
}

TEST_F(FleetShards, ARegionAsksOnlyTheShardsThatHoldItAndAnswersAsOneServer) {
  FleetDatabase fleet(url());
  push_sharded(fleet);
  EXPECT_EQ(fleet.shards(), (std::vector<std::pair<int, std::string>>{{1, "a"}, {2, "b"}}));
  // Every row is on the shard of its tile, none on the coordinator.
  EXPECT_EQ(shard_sql(0, "SELECT count(*) FROM slamvdb.submaps"), "3");
  EXPECT_EQ(shard_sql(1, "SELECT count(*) FROM slamvdb.submaps"), "3");
  EXPECT_EQ(shard_sql(0, "SELECT sum(blocks) = (SELECT count(*) FROM slamvdb.occupancy) FROM slamvdb.submaps"), "t");
  EXPECT_EQ(shard_sql(1, "SELECT count(DISTINCT submap) FROM slamvdb.semantics WHERE shard = 2"), "3");
  EXPECT_EQ(psql_value(coordinator_server(), "SELECT string_agg(tile_x || ':' || shard, ',' ORDER BY tile_x) FROM slamvdb.tiles",
                       coordinator_),
            "0:1,4:2");
  EXPECT_EQ(psql_value(coordinator_server(), "SELECT count(*) FROM ONLY slamvdb.submaps", coordinator_), "0");

  // The same pushes into one server answer the same, submap for submap and voxel for voxel.
  const std::string plain = slamvdb::testing::fresh_test_database(coordinator_server(), "_plain");
  FleetDatabase one(coordinator_server().url(plain));
  one.push_map(monday_, {.session = "monday"});
  one.push_map(tuesday_, {.session = "tuesday", .T_fleet_session = T_fleet_tuesday_});
  slamvdb::testing::expect_identical(shards_region_of(coordinator_server().url(plain), box(-1e4, 1e4), monday_),
                                     shards_region_of(url(), box(-1e4, 1e4), monday_));

  // Which server answered: each shard's statement log, before and after each region.
  std::size_t a = statements(0), b = statements(1);
  EXPECT_EQ(shards_region_of(url(), box(-50, 300), monday_).submaps().size(), 3u);
  EXPECT_GT(statements(0), a);
  EXPECT_EQ(statements(1), b) << "the west region asked shard b";
  a = statements(0), b = statements(1);
  EXPECT_EQ(shards_region_of(url(), box(1950, 2300), monday_).submaps().size(), 3u);
  EXPECT_EQ(statements(0), a) << "the east region asked shard a";
  EXPECT_GT(statements(1), b);
  a = statements(0), b = statements(1);
  EXPECT_EQ(shards_region_of(url(), box(500, 1500), monday_).submaps().size(), 0u);  // between the tiles: nobody
  EXPECT_EQ(statements(0), a);
  EXPECT_EQ(statements(1), b);

  // Idempotent through the shards; a correction moves anchors on the shard and grows the tile.
  const PushReport again = fleet.push_map(tuesday_, {.session = "tuesday", .T_fleet_session = T_fleet_tuesday_});
  EXPECT_EQ(again.submaps_unchanged, 3);
  EXPECT_EQ(again.rows_written, 0u);
  const PushReport moved =
      fleet.push_map(tuesday_, {.session = "tuesday", .T_fleet_session = slamvdb::testing::make_pose(0.0, {2000, 400, 0})});
  EXPECT_EQ(moved.anchors_moved, 3);
  EXPECT_EQ(shard_sql(1, "SELECT string_agg(revision::text, ',') FROM slamvdb.submaps"), "2,2,2");
  EXPECT_EQ(shards_region_of(url(), {Vec3d(1950, 390, -1e3), Vec3d(2300, 420, 1e3)}, monday_).submaps().size(), 3u);

  // A fleet that already holds submaps in its own tables is not split afterwards.
  const std::string refused = slamvdb::testing::error_of([&] { one.add_shard("c", shard_server(0).url(shard_db_[0])); });
  EXPECT_NE(refused.find("holds submaps in its own tables"), std::string::npos) << refused;
}

TEST_F(FleetShards, ADeadShardFailsOnlyTheRegionsItHoldsWithExitOneAndQuickly) {
  {
    FleetDatabase fleet(url());
    push_sharded(fleet, true);
  }
  slamvdb::testing::TempDir tmp;
  const std::string pull = slamvdb::testing::shell_quote(SLAMVDB_CLI_PATH) + " --quiet pull --db " + slamvdb::testing::shell_quote(url());
  shard_server(1).stop();
  struct Restart {
    ~Restart() { shard_server(1).start(); }
  } restart;
  const auto west = slamvdb::testing::run_command(pull + " --near 100,0 --radius 150 -o " +
                                                   slamvdb::testing::quote_path(tmp.path / "west.svdb") + " 2>&1");
  EXPECT_EQ(west.exit_code, 0) << west.output;
  EXPECT_TRUE(std::filesystem::exists(tmp.path / "west.svdb"));
  // A robot in the west still pushes (its submaps are unchanged: nothing to write, but asked).
  EXPECT_EQ(FleetDatabase(url()).push_map(monday_, {.session = "monday"}).submaps_unchanged, 3);

  const auto t0 = std::chrono::steady_clock::now();
  const auto east = slamvdb::testing::run_command(pull + " --near 2100,0 --radius 150 -o " +
                                                   slamvdb::testing::quote_path(tmp.path / "east.svdb") + " 2>&1");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(east.exit_code, 1) << east.output;
  EXPECT_NE(east.output.find("slamvdb_shard_b"), std::string::npos) << east.output;
  EXPECT_NE(east.output.find("a shard of this fleet is down"), std::string::npos) << east.output;
  EXPECT_LT(seconds, 15.0);
  EXPECT_FALSE(std::filesystem::exists(tmp.path / "east.svdb"));
  const std::string push = slamvdb::testing::error_of(
      [&] { FleetDatabase(url()).push_map(tuesday_, {.session = "tuesday", .T_fleet_session = T_fleet_tuesday_}); });
  EXPECT_NE(push.find("slamvdb_shard_b"), std::string::npos) << push;
}

}  // namespace
}  // namespace slamvdb::fleet
