// tf through the commands, on recordings the independent writers make (tests/recording_fixtures):
// a LiDAR-camera joint on /tf (moving extrinsics, looked up at each image's stamp), poses from tf
// (--pose-frame, --sensor-frame) and the tf tree in `inspect`.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
// Named, not anonymous: the unity build merges test files.
namespace recording_tf_commands_test {

namespace fs = std::filesystem;
using testing::quote_path;
using testing::run_command;

class RecordingTfCommands : public testing::RecordingFixtureTest {
 protected:
  static testing::CommandResult slamvdb(const std::string& args) {
    return run_command("exec " + quote_path(SLAMVDB_CLI_PATH) + " " + args + " 2>&1", 300.0);
  }
  // The MCAP with the ground-truth poses also on /tf (map -> os1_sensor), written once.
  static const fs::path& tf_poses_mcap() {
    static const fs::path file = write("write_mcap.mjs", "tf_poses.mcap", "--profile ros2 --tf-poses");
    return file;
  }
};

TEST_F(RecordingTfCommands, MovingExtrinsicsAreLookedUpAtEachImage) {
  // The same joint on /tf_static, on /tf unchanging, and on /tf turning at 0.5 rad/s.
  const fs::path fixed = write("write_mcap.mjs", "fixed.mcap", "--profile ros2");
  const fs::path still = write("write_mcap.mjs", "still.mcap", "--profile ros2 --moving-camera 0");
  const fs::path turning = write("write_mcap.mjs", "turning.mcap", "--profile ros2 --moving-camera 0.5");
  const std::string features = " --feature-size 48x32 --dim 16 --sim-encoder clean";
  std::map<std::string, SemanticMap> maps;
  for (const auto& [name, input] : {std::pair{"fixed", fixed}, {"still", still}, {"turning", turning}}) {
    const fs::path out = dir() / (std::string(name) + ".svdb");
    const auto r = slamvdb("map " + quote_path(input) + " -o " + quote_path(out) + features);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(r.output.find("images: 0 fused"), std::string::npos) << r.output;
    if (std::string(name) != "fixed") {
      EXPECT_NE(r.output.find("moving: looked up at each image's stamp"), std::string::npos) << r.output;
    }
    maps.emplace(name, load_map(out));
  }
  // An unchanging joint on /tf fuses exactly as the static one; a turning one fuses elsewhere.
  testing::expect_same_index_cells(maps.at("fixed"), maps.at("still"));
  const auto fixed_cells = testing::index_cells(maps.at("fixed")), turning_cells = testing::index_cells(maps.at("turning"));
  ASSERT_GT(fixed_cells.size(), 0u);
  std::size_t differ = fixed_cells.size() != turning_cells.size() ? 1 : 0;
  for (auto a = fixed_cells.begin(), b = turning_cells.begin(); !differ && a != fixed_cells.end(); ++a, ++b)
    differ += a->first != b->first || a->second.embedding != b->second.embedding;
  EXPECT_GT(differ, 0u) << "the turning camera fused the same cells as the fixed one";
  // The occupancy does not depend on the camera.
  EXPECT_EQ(testing::occupied_voxel_log_odds(maps.at("fixed")), testing::occupied_voxel_log_odds(maps.at("turning")));
}

TEST_F(RecordingTfCommands, PoseFrameGivesTheSameMapAsThePoseTopic) {
  const fs::path mcap = tf_poses_mcap();
  const auto from_topic = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "topic.svdb") +
                                  " --features none --pose-topic /ground_truth/odom");
  ASSERT_EQ(from_topic.exit_code, 0) << from_topic.output;
  const auto from_tf = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "tf.svdb") +
                               " --features none --pose-frame map --sensor-frame os1_sensor");
  ASSERT_EQ(from_tf.exit_code, 0) << from_tf.output;
  EXPECT_NE(from_tf.output.find("poses: tf map -> os1_sensor at each scan's stamp"), std::string::npos)
      << from_tf.output;
  const auto topic_voxels = testing::occupied_voxel_log_odds(load_map(dir() / "topic.svdb"));
  EXPECT_GT(topic_voxels.size(), 1000u);
  EXPECT_EQ(topic_voxels, testing::occupied_voxel_log_odds(load_map(dir() / "tf.svdb")));
  // The sensor frame defaults to the LiDAR's; through the static joint, the camera's pose is
  // moved to the LiDAR and gives the same map again.
  const auto via_camera = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "tf_camera.svdb") +
                                  " --features none --pose-frame map --sensor-frame pylon_camera");
  ASSERT_EQ(via_camera.exit_code, 0) << via_camera.output;
  const auto camera_voxels = testing::occupied_voxel_log_odds(load_map(dir() / "tf_camera.svdb"));
  EXPECT_EQ(camera_voxels.size(), topic_voxels.size());
}

TEST_F(RecordingTfCommands, PoseFrameUsageErrors) {
  const fs::path mcap = tf_poses_mcap();
  const std::string map = "map " + quote_path(mcap) + " -o " + quote_path(dir() / "bad.svdb") + " --features none ";
  auto r = slamvdb(map + "--pose-frame odom");  // no such frame: the frames seen are listed
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--pose-frame 'odom'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("map, os1_sensor, pylon_camera"), std::string::npos) << r.output;
  r = slamvdb(map + "--pose-frame map --sensor-frame base_link");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--sensor-frame 'base_link'"), std::string::npos) << r.output;
  r = slamvdb(map + "--pose-frame map --pose-topic /ground_truth/odom");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--pose-topic"), std::string::npos) << r.output;
  r = slamvdb(map + "--pose-frame map --poses " + quote_path(dir() / "seq" / "poses.txt"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--poses"), std::string::npos) << r.output;
  r = slamvdb(map + "--sensor-frame os1_sensor");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

TEST_F(RecordingTfCommands, InspectDrawsTheTfTree) {
  const fs::path mcap = tf_poses_mcap();
  const auto text = slamvdb("inspect " + quote_path(mcap));
  ASSERT_EQ(text.exit_code, 0) << text.output;
  const auto written = testing::read_manifest(manifest_of(mcap));
  const auto scans = static_cast<std::size_t>(
      std::count_if(written.begin(), written.end(), [](const testing::WrittenMessage& m) { return m.topic == "/tf"; }));
  ASSERT_GT(scans, 1u);  // one per scan
  // map at the root, os1_sensor under it (moving), pylon_camera under os1_sensor (static).
  const std::string tree = "    map\n      os1_sensor  (dynamic: " + std::to_string(scans) +
                           " transforms, 10.0 Hz)\n        pylon_camera  (static, 1 transform)\n";
  EXPECT_NE(text.output.find(tree), std::string::npos) << tree << "\n" << text.output;
  const auto json = slamvdb("inspect --json " + quote_path(mcap));
  ASSERT_EQ(json.exit_code, 0) << json.output;
  const auto tf = nlohmann::json::parse(json.output).at("tf");
  ASSERT_EQ(tf.size(), 2u);
  for (const auto& edge : tf) {
    if (edge.at("child") == "os1_sensor") {
      EXPECT_EQ(edge.at("parent"), "map");
      EXPECT_FALSE(edge.at("static").get<bool>());
      EXPECT_EQ(edge.at("transforms").get<std::size_t>(), scans);
      EXPECT_NEAR(edge.at("rate_hz").get<double>(), 10.0, 0.5);
    } else {
      EXPECT_EQ(edge.at("parent"), "os1_sensor");
      EXPECT_EQ(edge.at("child"), "pylon_camera");
      EXPECT_TRUE(edge.at("static").get<bool>());
      EXPECT_EQ(edge.at("transforms").get<std::size_t>(), 1u);
    }
  }
}

}  // namespace recording_tf_commands_test
}  // namespace slamvdb
