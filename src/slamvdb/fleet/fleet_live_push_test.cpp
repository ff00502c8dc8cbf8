// `map|slam --push`: the fleet gets each submap as the mapper finishes it (FleetPushingStore on the
// checkpoint path), corrections as anchor updates, merges as one submap replaced and one removed;
// the fleet then holds what a `push` of the finished map file gives, row for row, and a repeated
// run writes nothing. A server lost mid-run stops the pushes, not the map file. Real PostgreSQL 15
// servers (testing/postgres_server.hpp); the CLI test maps a short SIMULATED drive.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/fleet/fleet_live_push.hpp"
#include "slamvdb/store/map_file_writer.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/fleet_fixtures.hpp"
#include "slamvdb/testing/fleet_rows.hpp"
#include "slamvdb/testing/postgres_server.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::fleet {
namespace {

using slamvdb::testing::fleet_rows;
using slamvdb::testing::psql_value;
using slamvdb::testing::quote_path;
using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;

Pose at(double x, double y) {
  Pose T = Pose::Identity();
  T.translation() = Vec3d(x, y, 0);
  return T;
}

TEST(FleetLivePush, CorrectionsMoveAnchorsMergesReplaceOnePayloadAndTheFleetEqualsThePushedFile) {
  slamvdb::testing::TempDir tmp;
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string live_db = slamvdb::testing::fresh_test_database(server, "_live");
  const std::string file_db = slamvdb::testing::fresh_test_database(server, "_file");
  // The mapper's map as it finishes three submaps (SIMULATED patches 100 m apart).
  SemanticMap map = slamvdb::testing::patch_map(3, 24);
  const auto path = tmp.path / "live.svdb";
  auto writer = MapFileWriter::create(path, map.params(), map.info());
  FleetPushingStore store(server.url(live_db), map.params(), map.info(), {.session = "live"});
  store.keep_in(*writer);
  for (const int id : {0, 1, 2}) store.save_finished(map, id);
  ASSERT_EQ(store.error(), "");
  EXPECT_EQ(store.report().submaps_added, 3);
  const uint64_t rows = store.report().rows_written;
  EXPECT_GT(rows, 0u);

  // A loop correction moves submaps 1 and 2 (2 onto 0): catalog rows only, no payload row written.
  const std::map<int, Pose> corrected{{0, at(0, 0)}, {1, at(100, 7)}, {2, at(0, 0)}};
  map.set_submap_poses(corrected);
  store.save_poses(corrected);
  EXPECT_EQ(store.report().anchors_moved, 2);
  EXPECT_EQ(store.report().rows_written, rows);
  EXPECT_EQ(psql_value(server, "SELECT string_agg(revision::text, ',' ORDER BY submap) FROM slamvdb.submaps", live_db),
            "1,2,2");
  EXPECT_EQ(psql_value(server, "SELECT ST_YMin(footprint) FROM slamvdb.submaps WHERE submap = 1", live_db), "7");

  // A merge (2 into 0): 0's payload replaced and 2's rows gone, in one transaction.
  ASSERT_TRUE(map.merge_submaps(0, 2, {.min_overlap = 0.0}).refused.empty());
  store.save_merge(map, 0, 2);
  ASSERT_EQ(store.error(), "");
  EXPECT_EQ(store.report().payloads_replaced, 1);
  EXPECT_EQ(store.report().submaps_removed, 1);
  EXPECT_EQ(psql_value(server, "SELECT string_agg(submap::text, ',' ORDER BY submap) FROM slamvdb.submaps", live_db),
            "0,1");
  EXPECT_EQ(psql_value(server, "SELECT count(*) FROM slamvdb.semantics WHERE submap = 2", live_db), "0");
  writer->finish(map.info(), 0);

  // The fleet pushed while mapping equals the push of the finished map file, row for row.
  FleetDatabase(server.url(file_db)).push_map(load_map(path), {.session = "live"});
  EXPECT_EQ(fleet_rows(server, live_db, false), fleet_rows(server, file_db, false));
  // A tile's extent only grows (docs/fleet-design.md, "Scale out"): the live fleet's holds the
  // footprints before and after the correction, the file's those after.
  const std::string tiles = "SELECT string_agg(concat_ws(',', tile_x, tile_y, x_min, y_min, x_max, y_max), ' ' ORDER BY tile_x, tile_y) FROM slamvdb.tiles";
  EXPECT_EQ(psql_value(server, tiles, live_db), "0,0,0,0,206,13");
  EXPECT_EQ(psql_value(server, tiles, file_db), "0,0,0,0,106,13");
  EXPECT_NE(fleet_rows(server, live_db).find("2:"), std::string::npos);
}

TEST(FleetLivePush, AServerLostMidRunStopsThePushesNotTheMapFile) {
  slamvdb::testing::TempDir tmp;
  slamvdb::testing::PostgresServer own(tmp.path);  // this test stops it
  own.psql("CREATE DATABASE fleet");
  const SemanticMap map = slamvdb::testing::patch_map(3, 16);
  const auto path = tmp.path / "kept.svdb";
  auto writer = MapFileWriter::create(path, map.params(), map.info());
  FleetPushingStore store(own.url("fleet"), map.params(), map.info(), {.session = "lost"});
  store.keep_in(*writer);
  store.save_finished(map, 0);
  ASSERT_EQ(store.error(), "");
  own.stop();
  EXPECT_NO_THROW(store.save_finished(map, 1));
  EXPECT_NE(store.error().find("push to the fleet database postgresql:///fleet"), std::string::npos) << store.error();
  EXPECT_NO_THROW(store.save_finished(map, 2));  // no retry once failed: mapping is not held up
  EXPECT_EQ(store.report().submaps_added, 1);
  writer->finish(map.info(), 0);
  EXPECT_EQ(load_map(path).num_submaps(), 3u);  // the map file has every submap
}

TEST(FleetLivePush, MapPushEqualsThePushOfItsFileAndARepeatedRunWritesNothing) {
  slamvdb::testing::TempDir tmp;
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string live_db = slamvdb::testing::fresh_test_database(server, "_live");
  const std::string file_db = slamvdb::testing::fresh_test_database(server, "_file");
  synth::SynthConfig config;  // a SIMULATED 30 m drive, small sensors: three or four submaps
  config.length_m = 30;
  config.speed_mps = 6;
  config.image_width = 64;
  config.image_height = 40;
  config.lidar.beams = 16;
  config.lidar.columns = 256;
  const auto seq = tmp.path / "seq";
  synth::write_synthetic_sequence(config, seq);
  const auto file = tmp.path / "drive.svdb";
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH) + " --quiet ";
  const std::string map = cli + "map " + quote_path(seq) + " -o " + quote_path(file) +
                          " --feature-size 16x10 --dim 8 --submap-length 10 --push " + shell_quote(server.url(live_db));
  const auto first = run_command(map + " 2>&1", 300);
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("fleet: "), std::string::npos) << first.output;
  const int submaps = std::stoi(psql_value(server, "SELECT count(*) FROM slamvdb.submaps", live_db));
  EXPECT_GE(submaps, 3);
  EXPECT_NE(first.output.find(fmt::format("fleet: {} submaps added, 0 unchanged", submaps)), std::string::npos)
      << first.output;
  const auto pushed = run_command(cli + "push " + quote_path(file) + " --db " + shell_quote(server.url(file_db)) + " 2>&1");
  ASSERT_EQ(pushed.exit_code, 0) << pushed.output;
  const std::string rows = fleet_rows(server, live_db);
  EXPECT_EQ(rows, fleet_rows(server, file_db));
  const std::string catalog = "SELECT string_agg(concat_ws(',', submap, time_begin, time_end, path_length, z_min, z_max, "
                              "ST_AsText(footprint), payload_crc, embedding_radius, embedding_centroid), E'\\n' "
                              "ORDER BY submap) FROM slamvdb.submaps";
  EXPECT_EQ(psql_value(server, catalog, live_db), psql_value(server, catalog, file_db));
  EXPECT_EQ(psql_value(server, "SELECT name FROM slamvdb.sessions", live_db), "drive");

  // The same run again (a crashed run repeated): every submap found unchanged, nothing written.
  const auto again = run_command(map + " 2>&1", 300);
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find(fmt::format("fleet: 0 submaps added, {} unchanged, 0 anchors moved, 0 payloads", submaps)),
            std::string::npos)
      << again.output;
  EXPECT_EQ(fleet_rows(server, live_db), rows);
  EXPECT_EQ(psql_value(server, "SELECT max(revision) FROM slamvdb.submaps", live_db), "1");

  // A fleet that is not there: exit 1 before mapping, no map file; usage errors exit 2.
  const auto other = tmp.path / "other.svdb";
  const std::string nowhere = "postgresql://robot:s3cret@/fleet?host=" + (tmp.path / "none").string();
  const auto down = run_command(cli + "map " + quote_path(seq) + " -o " + quote_path(other) + " --push " +
                                shell_quote(nowhere) + " 2>&1");
  EXPECT_EQ(down.exit_code, 1) << down.output;
  EXPECT_NE(down.output.find("cannot connect to the fleet database postgresql://robot:***@"), std::string::npos)
      << down.output;
  EXPECT_FALSE(std::filesystem::exists(other));
  const std::string base = cli + "map " + quote_path(seq) + " -o " + quote_path(other);
  EXPECT_EQ(run_command(base + " --push-session x 2>&1").exit_code, 2);
  EXPECT_EQ(run_command(base + " --push " + shell_quote(nowhere) + " --no-checkpoints 2>&1").exit_code, 2);
}

}  // namespace
}  // namespace slamvdb::fleet
