// Pushing maps into a fleet on a real PostgreSQL 15 + PostGIS server the test starts: rows and
// footprints arrive, a repeated push writes nothing, a moved anchor rewrites the catalog row only,
// a map of another embedding space is refused before any write, two robots push at once, and a
// server killed mid-push leaves whole submaps only. Checked with psql, a client that is not ours.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <thread>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::blocks_of;
using slamvdb::testing::patch_map;
using slamvdb::testing::PostgresServer;

class FleetPush : public ::testing::Test {
 protected:
  void SetUp() override { db_ = slamvdb::testing::fresh_test_database(server()); }
  static PostgresServer& server() { return slamvdb::testing::shared_postgres_server(); }
  std::string sql(const std::string& query) const { return slamvdb::testing::psql_value(server(), query, db_); }
  std::string url() const { return server().url(db_); }
  // The submaps whose footprint meets the box, as "session:submap" (PostGIS answers, not ours).
  std::string submaps_in(double x0, double y0, double x1, double y1) const {
    return sql(fmt::format("SELECT string_agg(s.name || ':' || m.submap, ',' ORDER BY s.name, m.submap) FROM "
                           "slamvdb.submaps m JOIN slamvdb.sessions s ON s.id = m.session WHERE m.footprint && "
                           "ST_MakeEnvelope({}, {}, {}, {}, 0)",
                           x0, y0, x1, y1));
  }
  std::string db_;
};

TEST_F(FleetPush, SubmapsArriveWithTheirRowsAndFootprintsAndARepeatedPushWritesNothing) {
  const SemanticMap map = patch_map(3, 40);
  FleetDatabase fleet(url());
  const PushReport first = fleet.push_map(map, {.session = "monday", .robot = "husky-1"});
  EXPECT_TRUE(first.session_created);
  EXPECT_EQ(first.submaps_added, 3);
  EXPECT_EQ(sql("SELECT count(*) FROM slamvdb.submaps"), "3");
  EXPECT_EQ(sql("SELECT count(*) FROM slamvdb.occupancy"), std::to_string(blocks_of(map)));
  EXPECT_EQ(sql("SELECT sum(length(embeddings)) FROM slamvdb.semantics"),
            std::to_string(map.num_semantic_voxels() * 4 * 2));  // fp16
  EXPECT_EQ(sql("SELECT robot || ' ' || time_begin || ' ' || time_end FROM slamvdb.sessions"), "husky-1 0 29");
  // A patch is 10 x 10 m from its anchor: the region queries find each where it lies.
  EXPECT_EQ(submaps_in(102, 2, 105, 5), "monday:1");
  EXPECT_EQ(submaps_in(-50, -50, 150, 5), "monday:0,monday:1");
  EXPECT_EQ(submaps_in(20, 20, 80, 80), "");

  const std::string payload_versions = sql("SELECT string_agg(xmin::text, ',') FROM slamvdb.occupancy");
  const PushReport again = FleetDatabase(url()).push_map(map, {.session = "monday", .robot = "husky-1"});
  EXPECT_FALSE(again.session_created);
  EXPECT_EQ(again.submaps_unchanged, 3);
  EXPECT_EQ(again.rows_written, 0u);
  EXPECT_EQ(sql("SELECT count(*) FROM slamvdb.occupancy"), std::to_string(blocks_of(map)));
  EXPECT_EQ(sql("SELECT string_agg(xmin::text, ',') FROM slamvdb.occupancy"), payload_versions);
  EXPECT_EQ(sql("SELECT max(revision) FROM slamvdb.submaps"), "1");
}

TEST_F(FleetPush, AMovedAnchorRewritesTheCatalogRowOnlyAndMovesTheFootprint) {
  SemanticMap map = patch_map(2, 30);
  FleetDatabase fleet(url());
  fleet.push_map(map, {.session = "monday"});
  const std::string payload_versions = sql("SELECT string_agg(xmin::text, ',') FROM slamvdb.occupancy");
  Pose moved = Pose::Identity();
  moved.translation() = Vec3d(100, 500, 0);  // a loop correction moved submap 1 by 500 m in y
  map.set_submap_poses({{1, moved}});
  const PushReport report = fleet.push_map(map, {.session = "monday"});
  EXPECT_EQ(report.anchors_moved, 1);
  EXPECT_EQ(report.submaps_unchanged, 1);
  EXPECT_EQ(report.rows_written, 0u);
  EXPECT_EQ(sql("SELECT string_agg(xmin::text, ',') FROM slamvdb.occupancy"), payload_versions);  // never payloads
  EXPECT_EQ(sql("SELECT string_agg(submap || ':' || revision, ',' ORDER BY submap) FROM slamvdb.submaps"), "0:1,1:2");
  EXPECT_EQ(submaps_in(101, 1, 104, 4), "");
  EXPECT_EQ(submaps_in(101, 501, 104, 504), "monday:1");

  // The session placed elsewhere in the fleet frame (an alignment): every footprint follows.
  Pose T_fleet_session = Pose::Identity();
  T_fleet_session.translation() = Vec3d(0, -1000, 0);
  const PushReport placed = fleet.push_map(map, {.session = "monday", .T_fleet_session = T_fleet_session});
  EXPECT_EQ(placed.anchors_moved, 2);
  EXPECT_EQ(submaps_in(1, -999, 4, -996), "monday:0");
  EXPECT_EQ(sql("SELECT string_agg(xmin::text, ',') FROM slamvdb.occupancy"), payload_versions);
}

TEST_F(FleetPush, AMapOfAnotherEmbeddingSpaceOrVoxelSizeIsRefusedBeforeAnythingIsWritten) {
  FleetDatabase fleet(url());
  fleet.push_map(patch_map(1, 10), {.session = "monday"});
  const std::string before = sql("SELECT (SELECT count(*) FROM slamvdb.sessions) || ' ' || (SELECT count(*) FROM "
                                 "slamvdb.submaps) || ' ' || (SELECT count(*) FROM slamvdb.occupancy)");
  const std::string space =
      slamvdb::testing::error_of([&] { fleet.push_map(patch_map(1, 10, "lseg-real"), {.session = "tuesday"}); });
  EXPECT_NE(space.find("'model_id': the fleet has 'fleet-test-space', the map 'lseg-real'"), std::string::npos) << space;
  const std::string voxel = slamvdb::testing::error_of(
      [&] { fleet.push_map(patch_map(1, 10, "fleet-test-space", 0.2), {.session = "tuesday"}); });
  EXPECT_NE(voxel.find("'voxel_size': the fleet has '0.25', the map '0.2'"), std::string::npos) << voxel;
  EXPECT_EQ(sql("SELECT (SELECT count(*) FROM slamvdb.sessions) || ' ' || (SELECT count(*) FROM slamvdb.submaps) || "
                "' ' || (SELECT count(*) FROM slamvdb.occupancy)"),
            before);
  EXPECT_NE(slamvdb::testing::error_of([&] { fleet.push_map(patch_map(1, 10), {.session = ""}); }), "");
}

TEST_F(FleetPush, TwoRobotsPushingAtOnceBothComplete) {
  const SemanticMap a = patch_map(4, 30), b = patch_map(4, 30);
  std::atomic<int> failures{0};
  const auto push = [&](const SemanticMap& map, const std::string& session) {
    try {
      FleetDatabase(url()).push_map(map, {.session = session});
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();
      ++failures;
    }
  };
  std::thread first(push, std::cref(a), "robot-a"), second(push, std::cref(b), "robot-b");
  first.join();
  second.join();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(sql("SELECT count(*) FROM slamvdb.submaps"), "8");
  EXPECT_EQ(sql("SELECT count(*) FROM slamvdb.occupancy"), std::to_string(blocks_of(a) + blocks_of(b)));
}

// Its own server, since the test kills it.
TEST(FleetPushCrash, AServerKilledMidPushLeavesWholeSubmapsAndARepeatedPushCompletes) {
  slamvdb::testing::TempDir tmp;
  PostgresServer server(tmp.path);
  const std::string url = server.url();
  const SemanticMap map = patch_map(40, 96);  // 40 submaps: the push takes about a second
  FleetDatabase(url).ensure_schema();
  std::atomic<bool> failed{false};
  std::string failure;
  std::thread pusher([&] {
    try {
      FleetDatabase(url).push_map(map, {.session = "monday"});
    } catch (const Error& e) {
      failure = e.what();
      failed = true;
    }
  });
  // Kill the server once some submaps are in.
  for (int i = 0; i < 2000 && slamvdb::testing::psql_value(server, "SELECT count(*) FROM slamvdb.submaps", "postgres") ==
                                  "0";
       ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  server.kill_hard();
  pusher.join();
  ASSERT_TRUE(failed) << "the push ended before the server was killed";
  EXPECT_NE(failure.find("push to the fleet database"), std::string::npos) << failure;

  server.start();
  const int in = std::stoi(slamvdb::testing::psql_value(server, "SELECT count(*) FROM slamvdb.submaps", "postgres"));
  EXPECT_GT(in, 0);
  EXPECT_LT(in, 40);
  // Whole submaps only: every catalog row has exactly its blocks and semantic chunks.
  EXPECT_EQ(slamvdb::testing::psql_value(server,
                                         "SELECT count(*) FROM slamvdb.submaps m WHERE m.blocks <> (SELECT count(*) "
                                         "FROM slamvdb.occupancy o WHERE o.session = m.session AND o.submap = "
                                         "m.submap) OR (SELECT count(*) FROM slamvdb.semantics s WHERE s.session = "
                                         "m.session AND s.submap = m.submap) <> (m.semantic_voxels + 4095) / 4096",
                                         "postgres"),
            "0");
  const PushReport completed = FleetDatabase(url).push_map(map, {.session = "monday"});
  EXPECT_EQ(completed.submaps_unchanged, in);
  EXPECT_EQ(completed.submaps_added, 40 - in);
  EXPECT_EQ(slamvdb::testing::psql_value(server, "SELECT count(*) FROM slamvdb.occupancy", "postgres"),
            std::to_string(blocks_of(map)));
}

}  // namespace
}  // namespace slamvdb::fleet
