// Recordings as inputs of the commands, end to end through the CLI: the same SIMULATED drive as a
// folder, a ROS 1 bag (Debian's python3-rosbag), an MCAP in each profile (@mcap/core) and a ROS 2
// bag folder (sqlite3 + @foxglove's CDR), written at test time by writers that are not ours, gives
// the same occupied voxels with `map` and the same poses with `odometry`. Topic choices, extrinsics
// from tf or --extrinsics, --pose-topic and damaged recordings through the CLI.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
// Named, not anonymous: the unity build merges test files.
namespace recording_commands_test {

namespace fs = std::filesystem;
using testing::occupied_voxels;
using testing::quote_path;
using testing::run_command;

class RecordingCommands : public testing::RecordingFixtureTest {
 protected:
  static fs::path seq() { return dir() / "seq"; }
  static std::string cli() { return quote_path(SLAMVDB_CLI_PATH); }
  static fs::path ros1_bag(const std::string& name, const std::string& options) {
    const fs::path out = dir() / name;
    const fs::path script = testing::recording_fixtures_dir() / "write_ros1_bag.py";
    const auto r = run_command("exec /usr/bin/python3 " + quote_path(script) + " " + quote_path(seq()) + " " +
                               quote_path(out) + " " + options + " 2>&1");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out;
  }
  // The containers, each written once per suite.
  static const std::vector<std::pair<std::string, fs::path>>& inputs() {
    static const std::vector<std::pair<std::string, fs::path>> all = {
        {"folder", seq()},
        {"ROS 1 bag (lz4)", ros1_bag("drive.bag", "--compression lz4")},
        {"MCAP ros1", write("write_mcap.mjs", "drive1.mcap", "--profile ros1 --compression lz4")},
        {"MCAP ros2", write("write_mcap.mjs", "drive2.mcap", "--profile ros2 --compression zstd")},
        {"ROS 2 bag", write("write_rosbag2.mjs", "drive_bag", "--split 2")}};
    return all;
  }
  static testing::CommandResult slamvdb(const std::string& args) {
    return run_command("exec " + cli() + " " + args + " 2>&1", 300.0);
  }
};


std::size_t non_blank_lines(const fs::path& file) {
  std::ifstream in(file);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) n += !line.empty();
  return n;
}

std::vector<double> numbers_in(const fs::path& file) {
  std::ifstream in(file);
  std::vector<double> v;
  for (double x; in >> x;) v.push_back(x);
  return v;
}

TEST_F(RecordingCommands, SameMapAndPosesWhicheverWayTheDriveComesIn) {
  std::map<std::tuple<int, int, int, int>, float> reference_voxels;
  std::vector<double> reference_poses;
  for (const auto& [name, input] : inputs()) {
    SCOPED_TRACE(name);
    const fs::path map_file = dir() / (input.filename().string() + ".svdb");
    const fs::path poses_file = dir() / (input.filename().string() + ".poses.txt");
    const auto mapped = slamvdb("map " + quote_path(input) + " -o " + quote_path(map_file) + " --features none");
    ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
    const auto tracked = slamvdb("odometry " + quote_path(input) + " -o " + quote_path(poses_file));
    ASSERT_EQ(tracked.exit_code, 0) << tracked.output;
    const auto voxels = occupied_voxels(map_file);
    const auto poses = numbers_in(poses_file);
    if (name == "folder") {
      reference_voxels = voxels;
      reference_poses = poses;
      ASSERT_GT(voxels.size(), 1000u);
      ASSERT_GE(poses.size(), 3u * 12u);
      continue;
    }
    EXPECT_NE(mapped.output.find("time source: header stamps"), std::string::npos) << mapped.output;
    EXPECT_NE(mapped.output.find("T_lidar_camera from tf (os1_sensor -> pylon_camera)"), std::string::npos)
        << mapped.output;
    EXPECT_TRUE(voxels == reference_voxels) << voxels.size() << " occupied voxels, the folder's map "
                                            << reference_voxels.size();
    ASSERT_EQ(poses.size(), reference_poses.size());
    EXPECT_EQ(poses, reference_poses);  // the same stamps and points: the same registrations
  }
}

TEST_F(RecordingCommands, SimulatedFeaturesFromTheLabelTopicAndSlam) {
  // The image path: label images from the recording feed the SIMULATED encoder; slam runs on it.
  const fs::path mcap = inputs()[3].second;
  const auto mapped = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "features.svdb") +
                              " --feature-size 48x32 --dim 16 --sim-encoder clean");
  ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
  EXPECT_NE(mapped.output.find("labels: /pylon_camera_node_label_id/image"), std::string::npos) << mapped.output;
  EXPECT_EQ(mapped.output.find("images: 0 fused"), std::string::npos) << mapped.output;
  const auto slam = slamvdb("slam " + quote_path(mcap) + " -o " + quote_path(dir() / "slam.svdb") +
                            " --feature-size 48x32 --dim 16 --sim-encoder clean");
  ASSERT_EQ(slam.exit_code, 0) << slam.output;
  EXPECT_EQ(slam.output.find("images: 0 fused"), std::string::npos) << slam.output;
}

TEST_F(RecordingCommands, TopicChoicesExtrinsicsAndPoseTopic) {
  const fs::path mcap = inputs()[3].second;
  // A topic option naming no such topic: a usage error listing the candidates.
  auto r = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "x.svdb") +
                   " --features none --lidar-topic /nope");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/os1_cloud_node/points"), std::string::npos) << r.output;
  // --pose-topic names the pose topic (chosen automatically too: the only one).
  r = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "p.svdb") +
              " --features none --pose-topic /ground_truth/odom");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("poses: /ground_truth/odom (--pose-topic)"), std::string::npos) << r.output;
  // --extrinsics replaces tf's transform and says so.
  r = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "e.svdb") +
              " --features none --extrinsics " + quote_path(seq() / "transforms.yaml"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("T_lidar_camera from --extrinsics"), std::string::npos) << r.output;
  // A KITTI pose file cannot be paired with a recording's scans.
  r = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "k.svdb") + " --features none --poses " +
              quote_path(seq() / "poses.txt"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("TUM"), std::string::npos) << r.output;
}

// A copy of the ROS 1 bag made with python3-rosbag: `extra` is a Python expression of the topic t
// giving the list of topics each message is written on.
fs::path rewritten_bag(const fs::path& in, const fs::path& out, const std::string& extra) {
  const std::string script = "import rosbag, sys\n"
                             "with rosbag.Bag(sys.argv[2], 'w') as o:\n"
                             "  for t, m, ts in rosbag.Bag(sys.argv[1]).read_messages(raw=True):\n"
                             "    for topic in (" + extra + "):\n"
                             "      o.write(topic, m, ts, raw=True)\n";
  const fs::path py = out.string() + ".py";
  std::ofstream(py) << script;
  const auto r = run_command("exec /usr/bin/python3 " + quote_path(py) + " " + quote_path(in) + " " + quote_path(out) +
                             " 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return out;
}

TEST_F(RecordingCommands, SeveralLidarTopicsAreAUsageErrorNoCameraIsGeometryOnly) {
  const fs::path bag = inputs()[1].second;
  const fs::path two = rewritten_bag(bag, dir() / "two_lidars.bag",
                                     "[t, '/velodyne_points'] if t == '/os1_cloud_node/points' else [t]");
  auto r = slamvdb("odometry " + quote_path(two) + " -o " + quote_path(dir() / "two.txt"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/os1_cloud_node/points"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("/velodyne_points"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--lidar-topic"), std::string::npos) << r.output;
  r = slamvdb("odometry " + quote_path(two) + " -o " + quote_path(dir() / "two.txt") + " --lidar-topic /velodyne_points");
  EXPECT_EQ(r.exit_code, 0) << r.output;

  const fs::path lidar_only =
      rewritten_bag(bag, dir() / "lidar_only.bag", "[] if 'pylon' in t else [t]");
  r = slamvdb("map " + quote_path(lidar_only) + " -o " + quote_path(dir() / "lidar_only.svdb"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("geometry only"), std::string::npos) << r.output;
  // Without /tf_static, a camera needs --extrinsics: the error says what is missing.
  const fs::path no_tf = rewritten_bag(bag, dir() / "no_tf.bag", "[] if t == '/tf_static' else [t]");
  r = slamvdb("map " + quote_path(no_tf) + " -o " + quote_path(dir() / "no_tf.svdb") + " --features none");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--extrinsics"), std::string::npos) << r.output;
  r = slamvdb("map " + quote_path(no_tf) + " -o " + quote_path(dir() / "no_tf.svdb") + " --features none --extrinsics " +
              quote_path(seq() / "transforms.yaml"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = slamvdb("map " + quote_path(bag) + " -o " + quote_path(dir() / "with_tf.svdb") + " --features none");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(occupied_voxels(dir() / "no_tf.svdb"), occupied_voxels(dir() / "with_tf.svdb"));
}

TEST_F(RecordingCommands, SeveralCameraOrLabelTopicsAreAUsageErrorListingThem) {
  const fs::path bag = inputs()[1].second;
  // A second camera: its images and camera info in a namespace of their own.
  const fs::path two_cameras = rewritten_bag(
      bag, dir() / "two_cameras.bag",
      "[t, t.replace('/pylon_camera_node/', '/camera2/')] if t.startswith('/pylon_camera_node/') else [t]");
  auto r = slamvdb("map " + quote_path(two_cameras) + " -o " + quote_path(dir() / "two_cameras.svdb") +
                   " --features none");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  for (const char* expected : {"/pylon_camera_node/image_raw/compressed", "/camera2/image_raw/compressed",
                               "--image-topic", "--label-topic", "--pose-topic"})
    EXPECT_NE(r.output.find(expected), std::string::npos) << expected << "\n" << r.output;
  r = slamvdb("map " + quote_path(two_cameras) + " -o " + quote_path(dir() / "two_cameras.svdb") +
              " --features none --image-topic /camera2/image_raw/compressed");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("/camera2/camera_info"), std::string::npos) << r.output;  // its namespace's CameraInfo
  // A second label topic.
  const fs::path two_labels = rewritten_bag(
      bag, dir() / "two_labels.bag", "[t, '/other_label/image'] if t == '/pylon_camera_node_label_id/image' else [t]");
  r = slamvdb("map " + quote_path(two_labels) + " -o " + quote_path(dir() / "two_labels.svdb") + " --features none");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  for (const char* expected : {"/pylon_camera_node_label_id/image", "/other_label/image", "--label-topic"})
    EXPECT_NE(r.output.find(expected), std::string::npos) << expected << "\n" << r.output;
}

TEST_F(RecordingCommands, TimeSourceLogFollowsTheRecordTimesHeaderStampsByDefault) {
  // The writer shifts every log time by 1000.25 s; the header stamps stay those of times.txt.
  const fs::path shifted = write("write_mcap.mjs", "shifted.mcap", "--profile ros2 --log-time-offset 1000.25");
  const auto stamps_of = [&](const std::string& options) {
    const fs::path out = dir() / "shifted_poses.txt";
    const auto r = slamvdb("odometry " + quote_path(shifted) + " -o " + quote_path(out) + " --format tum" + options);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    std::vector<double> stamps;
    std::ifstream in(out);
    for (std::string line; std::getline(in, line);)
      if (!line.empty() && line[0] != '#') stamps.push_back(std::stod(line));
    return std::make_pair(stamps, r.output);
  };
  const auto [header, header_output] = stamps_of("");
  const auto [log, log_output] = stamps_of(" --time-source log");
  EXPECT_NE(header_output.find("time source: header stamps"), std::string::npos) << header_output;
  EXPECT_NE(log_output.find("time source: log (record) times"), std::string::npos) << log_output;
  const std::vector<double> written = numbers_in(seq() / "times.txt");
  ASSERT_EQ(header.size(), written.size());
  ASSERT_EQ(log.size(), written.size());
  for (std::size_t i = 0; i < written.size(); ++i) {
    EXPECT_NEAR(header[i], written[i], 1e-5);  // header stamps: unaffected by the shift
    EXPECT_NEAR(log[i], written[i] + 1000.25, 1e-5);
  }
}

TEST_F(RecordingCommands, RealtimeReplaysARecordingAtItsRecordedRate) {
  // A 10 m SIMULATED drive (about 2 s of scans) as an MCAP; --realtime takes at least its span and
  // maps the same voxels as reading as fast as possible.
  const fs::path seq10 = dir() / "seq10";
  auto r = slamvdb("synth " + quote_path(seq10) + " --length 10 --image-size 160x100 --lidar-columns 256");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const fs::path mcap = dir() / "drive10.mcap";
  ASSERT_TRUE(testing::run_fixture_writer("write_mcap.mjs", quote_path(seq10) + " " + quote_path(mcap) + " --profile ros2"));
  const std::vector<double> stamps = numbers_in(seq10 / "times.txt");
  ASSERT_GE(stamps.size(), 10u);
  const double span = stamps.back() - stamps.front();
  r = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "fast.svdb") + " --features none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto start = std::chrono::steady_clock::now();
  r = slamvdb("map " + quote_path(mcap) + " -o " + quote_path(dir() / "paced.svdb") + " --features none --realtime");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_GE(seconds, span) << r.output;
  EXPECT_NE(r.output.find("real time: kept up with " + std::to_string(stamps.size()) + " of " +
                          std::to_string(stamps.size()) + " scans"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(occupied_voxels(dir() / "paced.svdb"), occupied_voxels(dir() / "fast.svdb"));
}

TEST_F(RecordingCommands, DamagedRecordingIsAClearErrorNeverACrash) {
  const fs::path mcap = inputs()[3].second;
  std::string bytes;
  {
    std::ifstream in(mcap, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  // Bytes overwritten in the middle (inside a chunk: its CRC or its zstd frame fails), and a file
  // cut in its first chunk (no channel left to read).
  std::string damaged = bytes;
  std::fill(damaged.begin() + static_cast<std::ptrdiff_t>(damaged.size() / 2),
            damaged.begin() + static_cast<std::ptrdiff_t>(damaged.size() / 2 + 64), '\x5a');
  std::ofstream(dir() / "damaged.mcap", std::ios::binary) << damaged;
  std::ofstream(dir() / "cut.mcap", std::ios::binary) << bytes.substr(0, bytes.size() / 10);
  for (const std::string file : {"damaged.mcap", "cut.mcap"})
    for (const std::string command : {"map", "slam", "odometry"}) {
      SCOPED_TRACE(file + " " + command);
      const auto r = slamvdb(command + " " + quote_path(dir() / file) + " -o " +
                             quote_path(dir() / ("out-" + command)) + (command == "odometry" ? "" : " --features none"));
      ASSERT_TRUE(r.exited()) << r.output;
      EXPECT_EQ(r.exit_code, 1) << r.output;
      EXPECT_NE(r.output.find(file), std::string::npos) << r.output;
    }
}

TEST_F(RecordingCommands, AMessageThatDoesNotDecodeIsAnErrorOrSkippedAndCounted) {
  // The second scan's bytes cut in half by python3-rosbag's raw writing: its header and layout
  // decode, its data is shorter than height x row_step.
  const fs::path bag = inputs()[1].second, bad = dir() / "bad_scan.bag";
  const fs::path py = dir() / "bad_scan.py";
  std::ofstream(py) << "import rosbag, sys\n"
                       "n = 0\n"
                       "with rosbag.Bag(sys.argv[2], 'w') as o:\n"
                       "  for t, m, ts in rosbag.Bag(sys.argv[1]).read_messages(raw=True):\n"
                       "    if t == '/os1_cloud_node/points':\n"
                       "      n += 1\n"
                       "      if n == 2: m = (m[0], m[1][:len(m[1]) // 2], m[2], m[3], m[4])\n"
                       "    o.write(t, m, ts, raw=True)\n";
  const auto written = run_command("exec /usr/bin/python3 " + quote_path(py) + " " + quote_path(bag) + " " +
                                   quote_path(bad) + " 2>&1");
  ASSERT_EQ(written.exit_code, 0) << written.output;
  auto r = slamvdb("odometry " + quote_path(bad) + " -o " + quote_path(dir() / "bad.txt"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("/os1_cloud_node/points message"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("does not decode"), std::string::npos) << r.output;
  r = slamvdb("map " + quote_path(bad) + " -o " + quote_path(dir() / "bad.svdb") + " --features none --skip-bad-messages");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("messages that do not decode 1 skipped"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("scans: " + std::to_string(non_blank_lines(seq() / "times.txt") - 1) + " integrated"),
            std::string::npos)
      << r.output;
}

TEST_F(RecordingCommands, InspectSaysWhatARecordingHoldsAndWhichTopicsItWouldUse) {
  for (const std::size_t i : {1u, 3u}) {
    const fs::path input = inputs()[i].second;
    SCOPED_TRACE(input.string());
    const auto text = slamvdb("inspect " + quote_path(input));
    ASSERT_EQ(text.exit_code, 0) << text.output;
    for (const char* expected : {"/os1_cloud_node/points  sensor_msgs/PointCloud2",
                                 "    os1_sensor\n      pylon_camera  (static, 1 transform)\n",
                                 "LiDAR: /os1_cloud_node/points (the only PointCloud2 topic)",
                                 "camera: /pylon_camera_node/image_raw/compressed with /pylon_camera_node/camera_info",
                                 "labels: /pylon_camera_node_label_id/image", "poses: /ground_truth/odom"})
      EXPECT_NE(text.output.find(expected), std::string::npos) << expected << "\n" << text.output;
    const auto json = slamvdb("inspect --json " + quote_path(input));
    ASSERT_EQ(json.exit_code, 0) << json.output;
    const auto j = nlohmann::json::parse(json.output);
    EXPECT_TRUE(j["recording"].get<bool>());
    const auto written = non_blank_lines(seq() / "times.txt");
    bool found = false;
    for (const auto& topic : j["topics"])
      if (topic["topic"] == "/os1_cloud_node/points") {
        found = true;
        EXPECT_EQ(topic["messages"].get<std::size_t>(), written);
        EXPECT_EQ(topic["type"], "sensor_msgs/PointCloud2");
        EXPECT_NEAR(topic["rate_hz"].get<double>(), 10.0, 0.5);  // synth's LiDAR rate
      }
    EXPECT_TRUE(found) << json.output;
    EXPECT_GT(j["duration_s"].get<double>(), 0.0);
  }
  const auto folder = slamvdb("inspect " + quote_path(seq()));
  ASSERT_EQ(folder.exit_code, 0) << folder.output;
  EXPECT_NE(folder.output.find("scans: " + std::to_string(non_blank_lines(seq() / "times.txt"))), std::string::npos)
      << folder.output;
}

}  // namespace recording_commands_test
}  // namespace slamvdb
