// `slam --push`: while `slam` maps a SIMULATED drive that closes a loop, the fleet gets each
// finished submap, the loop corrections as anchor updates and the merges as one submap replaced
// and one removed (docs/fleet-design.md, "Pushing while mapping"). At the end the fleet holds
// exactly the saved map file's submaps, anchors and payloads (row for row what `push` of the file
// writes into a second database), the merged-away submaps are gone, and a `push` of the file into
// the same fleet writes nothing. A real PostgreSQL 15 server (testing/postgres_server.hpp).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <regex>
#include <set>
#include <string>

#include "slamvdb/fleet/fleet_rows.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
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

// The submaps `slam` reports merged into another ("submap 3 merged into 0").
std::set<int> merged_away_in(const std::string& slam_output) {
  std::set<int> out;
  const std::regex pattern("submap (\\d+) merged into");
  for (auto it = std::sregex_iterator(slam_output.begin(), slam_output.end(), pattern); it != std::sregex_iterator(); ++it)
    out.insert(std::stoi((*it)[1]));
  return out;
}

TEST(FleetSlamPush, TheFleetHoldsTheSavedMapAfterCorrectionsAndMergesAndARepeatedPushWritesNothing) {
  slamvdb::testing::TempDir tmp;
  auto& server = slamvdb::testing::shared_postgres_server();
  const std::string live_db = slamvdb::testing::fresh_test_database(server, "_live");
  const std::string file_db = slamvdb::testing::fresh_test_database(server, "_file");
  // A SIMULATED 70 m drive around a 60 m loop (the shortest the scene builds), 1 m between scans,
  // small sensors: the loop closes in its last 10 m, submaps are moved and two merged (measured).
  synth::SynthConfig config;
  config.seed = 2;
  config.length_m = 70;
  config.min_loop_m = 60;
  config.speed_mps = 10;
  config.image_width = 64;
  config.image_height = 40;
  config.lidar.columns = 256;
  const auto seq = tmp.path / "seq";
  synth::write_synthetic_sequence(config, seq);
  const auto file = tmp.path / "drive.svdb";
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH) + " ";
  // A SIMULATED heading drift (4 degrees per 100 m) so that the corrections move the anchors.
  const auto slam = run_command(cli + "slam " + quote_path(seq) + " -o " + quote_path(file) +
                                    " --feature-size 16x10 --dim 8 --submap-length 15 --sim-odometry-drift 4 --push " +
                                    shell_quote(server.url(live_db)) + " 2>&1",
                                300);
  ASSERT_EQ(slam.exit_code, 0) << slam.output;
  const std::set<int> merged_away = merged_away_in(slam.output);
  ASSERT_FALSE(merged_away.empty()) << slam.output;
  EXPECT_EQ(slam.output.find("moved by 0 corrections"), std::string::npos) << slam.output;
  // A merge's source is removed from the fleet when it was pushed before it merged (the mapper's
  // threads decide whether the last one finished first: 1 or 2 of the 2 merges here, seen both).
  std::smatch fleet;
  ASSERT_TRUE(std::regex_search(slam.output, fleet,
                                std::regex("fleet: (\\d+) submaps added, 0 unchanged, (\\d+) anchors moved, (\\d+) "
                                           "payloads replaced, (\\d+) removed")))
      << slam.output;
  const int added = std::stoi(fleet[1]), moved = std::stoi(fleet[2]), replaced = std::stoi(fleet[3]),
            removed = std::stoi(fleet[4]);
  EXPECT_GT(moved, 0);
  EXPECT_GE(replaced, 1);
  EXPECT_GE(removed, 1);
  EXPECT_LE(removed, static_cast<int>(merged_away.size()));

  // The fleet holds the saved map's submaps, each at the saved map's (corrected) anchor.
  const SemanticMap map = load_map(file);
  std::string ids;
  for (const SubmapInfo& s : map.submaps()) {
    ids += (ids.empty() ? "" : ",") + std::to_string(s.id);
    EXPECT_FALSE(merged_away.count(s.id)) << s.id;
    const std::string anchor = psql_value(
        server, fmt::format("SELECT t_world_submap FROM slamvdb.submaps WHERE submap = {}", s.id), live_db);
    EXPECT_TRUE(parse_pose_array(anchor, "anchor").matrix() == s.T_world_submap.matrix()) << s.id << ": " << anchor;
  }
  EXPECT_EQ(psql_value(server, "SELECT string_agg(submap::text, ',' ORDER BY submap) FROM slamvdb.submaps", live_db),
            ids);
  EXPECT_EQ(added - removed, static_cast<int>(map.num_submaps()));
  // Some anchor was rewritten by a correction after its submap was first pushed.
  EXPECT_NE(psql_value(server, "SELECT max(revision) FROM slamvdb.submaps", live_db), "1");

  // Row for row (payloads, footprints, statistics, session) what `push` of the file writes.
  const std::string push_file = cli + "push " + quote_path(file) + " --db ";
  const auto pushed = run_command(push_file + shell_quote(server.url(file_db)) + " 2>&1");
  ASSERT_EQ(pushed.exit_code, 0) << pushed.output;
  // Every table but the homes: a submap's home tile is that of its footprint's centre when first
  // pushed, kept for good (docs/fleet-design.md, "Scale out"); a merge that moves the target's
  // centre across a tile edge (here submap 0's, from x >= 0 to -3.8 m, measured) leaves the live fleet's
  // home where it was. The same submaps have a home.
  const auto without_homes = [&](const std::string& db) {
    const std::string rows = fleet_rows(server, db, false);
    std::size_t at = 0;
    for (int table = 0; table < 5; ++table) at = rows.find(" | ", at) + 3;  // fleet, sessions, submaps, payloads
    return rows.substr(0, at);
  };
  EXPECT_EQ(without_homes(live_db), without_homes(file_db));
  EXPECT_EQ(psql_value(server, "SELECT string_agg(submap::text, ',' ORDER BY submap) FROM slamvdb.submap_homes", live_db),
            ids);
  const std::string rows = fleet_rows(server, live_db);
  const std::string revisions = "SELECT string_agg(revision::text, ',' ORDER BY submap) FROM slamvdb.submaps";
  const std::string revisions_before = psql_value(server, revisions, live_db);

  // The file pushed into the fleet it was pushed to while mapping: every submap unchanged.
  const auto again = run_command(push_file + shell_quote(server.url(live_db)) + " 2>&1");
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find(fmt::format("submaps    0 added, {} unchanged, 0 anchors moved, 0 payloads replaced",
                                          map.num_submaps())),
            std::string::npos)
      << again.output;
  EXPECT_NE(again.output.find("written    0 payload rows"), std::string::npos) << again.output;
  EXPECT_EQ(fleet_rows(server, live_db), rows);
  EXPECT_EQ(psql_value(server, revisions, live_db), revisions_before);
}

}  // namespace
}  // namespace slamvdb::fleet
