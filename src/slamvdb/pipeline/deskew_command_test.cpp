// Deskewing through the CLI: a SIMULATED drive swept over 0.1 s per scan (synth's lidar_sweep_s),
// recorded as an MCAP with per-point `t` by the fixture writer (tests/recording_fixtures, not our
// code), is deskewed by `map` with its ground-truth pose topic and by `slam` with the odometry's
// motion, and the run reports say so; with --no-deskew it is fused as read (another map).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
// Named, not anonymous: the unity build merges test files.
namespace deskew_command_test {

namespace fs = std::filesystem;
using testing::quote_path;

class DeskewCommands : public testing::RecordingFixtureTest {
 protected:
  // Hides the base's: the sequence is swept, and its per-point times go into the recording.
  static void SetUpTestSuite() {
    dir() = fs::temp_directory_path() / ("slamvdb-deskew-test-" + std::to_string(::getpid()));
    fs::remove_all(dir());
    synth::SynthConfig config = testing::recording_sequence_config();
    config.lidar_sweep_s = 0.1;
    testing::write_recording_sequence(dir() / "seq", config);
  }
  static fs::path recording() {
    static const fs::path mcap =
        write("write_mcap.mjs", "swept.mcap",
              "--profile ros2 --point-times " + quote_path(dir() / "seq" / synth::kPointTimesDir));
    return mcap;
  }
  static testing::CommandResult slamvdb(const std::string& args) {
    return testing::run_command("exec " + quote_path(SLAMVDB_CLI_PATH) + " " + args + " 2>&1", 300.0);
  }
};

TEST_F(DeskewCommands, MapAndSlamDeskewScansWithPointTimesUnlessTold) {
  const fs::path deskewed = dir() / "deskewed.svdb", raw = dir() / "raw.svdb";
  const auto with = slamvdb("map " + quote_path(recording()) + " -o " + quote_path(deskewed) + " --features none");
  ASSERT_EQ(with.exit_code, 0) << with.output;
  EXPECT_NE(with.output.find("deskewing: 4 of 4 scans with per-point times deskewed, motion from the poses"),
            std::string::npos)
      << with.output;
  const auto without = slamvdb("map " + quote_path(recording()) + " -o " + quote_path(raw) +
                               " --features none --no-deskew");
  ASSERT_EQ(without.exit_code, 0) << without.output;
  EXPECT_NE(without.output.find("deskewing: off; 4 scans with per-point times fused as read"), std::string::npos)
      << without.output;
  // The vehicle moves 0.5 m during each sweep: deskewing changes the map.
  EXPECT_NE(load_map(deskewed).num_occupied_voxels(), load_map(raw).num_occupied_voxels());

  // slam: the odometry's motion, known from the third scan on.
  const auto slam = slamvdb("slam " + quote_path(recording()) + " -o " + quote_path(dir() / "slam.svdb") +
                            " --features none");
  ASSERT_EQ(slam.exit_code, 0) << slam.output;
  EXPECT_NE(slam.output.find("deskewing: 2 of 4 scans with per-point times deskewed, motion from the odometry's"),
            std::string::npos)
      << slam.output;
  // The folder itself carries no per-point times (os1_cloud_node_point_times/ is for the writers).
  const auto folder = slamvdb("map " + quote_path(dir() / "seq") + " -o " + quote_path(dir() / "folder.svdb") +
                              " --features none");
  ASSERT_EQ(folder.exit_code, 0) << folder.output;
  EXPECT_NE(folder.output.find("deskewing: no scan has per-point times"), std::string::npos) << folder.output;
}

}  // namespace deskew_command_test
}  // namespace slamvdb
