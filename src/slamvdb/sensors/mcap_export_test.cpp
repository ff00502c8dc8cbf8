// A SIMULATED drive written as MCAP by slamvdb's own writer (`slamvdb synth --format mcap`,
// `slamvdb convert`), checked end to end through the CLI: an independent reader (@mcap/core with
// CRC checks, @foxglove's CDR reader: tests/recording_fixtures/read_mcap.mjs) reads every message
// and decodes it, and what it finds is the sequence's (counts, a point, image sizes, a pose, the
// extrinsics); `map` on the recording gives the folder's occupied voxels; writing is deterministic.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
// Named, not anonymous: the unity build merges test files.
namespace mcap_export_test {

namespace fs = std::filesystem;
using testing::quote_path;
using testing::run_command;

class McapExport : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir() = fs::temp_directory_path() / ("slamvdb-mcap-export-test-" + std::to_string(::getpid()));
    fs::remove_all(dir());
    fs::create_directories(dir());
    // A 2 m SIMULATED drive (5 scans of 64 x 256 points, 2 camera images of 160 x 100).
    const auto r =
        slamvdb("synth " + quote_path(seq()) + " --length 2 --image-size 160x100 --lidar-columns 256 --format mcap");
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() { fs::remove_all(dir()); }
  static fs::path& dir() {
    static fs::path d;
    return d;
  }
  static fs::path seq() { return dir() / "seq"; }
  static fs::path mcap() { return seq() / "drive.mcap"; }
  static testing::CommandResult slamvdb(const std::string& args) {
    return run_command("exec " + quote_path(SLAMVDB_CLI_PATH) + " " + args + " 2>&1", 300.0);
  }
  // read_mcap.mjs's JSON for `file`.
  static nlohmann::json independent_read(const fs::path& file) {
    const auto r = run_command("exec node " + quote_path(testing::recording_fixtures_dir() / "read_mcap.mjs") + " " +
                                   quote_path(file) + " 2>&1",
                               120.0);
    EXPECT_EQ(r.exit_code, 0) << "is node with tests/recording_fixtures/node_modules there? (scripts/setup.sh)\n"
                              << r.output;
    return r.exit_code == 0 ? nlohmann::json::parse(r.output) : nlohmann::json::object();
  }
};

std::vector<std::uint8_t> bytes_of(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST_F(McapExport, AnIndependentReaderReadsEveryMessageAsTheSequenceHasIt) {
  const Sequence sequence = read_sequence(seq());
  ASSERT_GE(sequence.scans.size(), 3u);
  ASSERT_GE(sequence.images.size(), 1u);
  const nlohmann::json j = independent_read(mcap());
  ASSERT_TRUE(j.contains("topics")) << j.dump();
  EXPECT_EQ(j["profile"], "ros2");
  EXPECT_TRUE(j["data_section_crc_ok"].get<bool>());
  const std::size_t scans = sequence.scans.size(), images = sequence.images.size();
  const auto count = [&](const char* topic) { return j["topics"][topic]["count"].get<std::size_t>(); };
  EXPECT_EQ(count("/os1_cloud_node/points"), scans);
  EXPECT_EQ(count("/ground_truth/odom"), scans);
  EXPECT_EQ(count("/pylon_camera_node/image_raw/compressed"), images);
  EXPECT_EQ(count("/pylon_camera_node/camera_info"), images);
  EXPECT_EQ(count("/pylon_camera_node_label_id/image"), images);
  EXPECT_EQ(count("/tf_static"), 1u);
  const std::size_t total = 2 * scans + 3 * images + 1;  // cloud + odom per scan, 3 per image, tf
  EXPECT_EQ(j["statistics"]["message_count"].get<std::size_t>(), total);
  EXPECT_EQ(j["messages_in_stream"].get<std::size_t>(), total);
  EXPECT_EQ(j["records"]["ChunkIndex"].get<int>(), j["chunks"].get<int>());
  EXPECT_GE(j["records"]["MessageIndex"].get<int>(), 6);  // one per channel and chunk

  // The first scan: every point, the first one's coordinates and intensity, t = 0 (no sweep times).
  const LidarScan scan = read_scan(sequence.scans.front());
  const auto& cloud = j["first"]["/os1_cloud_node/points"];
  EXPECT_EQ(cloud["width"].get<std::size_t>(), scan.points.size());
  EXPECT_EQ(cloud["frame_id"], "os1_sensor");
  EXPECT_EQ(cloud["fields"], nlohmann::json({"x:0:7", "y:4:7", "z:8:7", "intensity:12:7", "t:16:6"}));
  EXPECT_EQ(cloud["first_point"]["x"].get<float>(), scan.points[0].x());
  EXPECT_EQ(cloud["first_point"]["y"].get<float>(), scan.points[0].y());
  EXPECT_EQ(cloud["first_point"]["z"].get<float>(), scan.points[0].z());
  EXPECT_EQ(cloud["last_point"]["z"].get<float>(), scan.points.back().z());
  EXPECT_EQ(cloud["first_point"]["intensity"].get<float>(), scan.intensity[0]);
  EXPECT_EQ(cloud["first_point"]["t"].get<int>(), 0);

  // The first image: the JPEG's bytes unchanged; the label image and CameraInfo at the camera's size.
  const auto jpeg = bytes_of(sequence.images.front().rgb);
  const auto& image = j["first"]["/pylon_camera_node/image_raw/compressed"];
  EXPECT_EQ(image["format"], "jpeg");
  EXPECT_EQ(image["bytes"].get<std::size_t>(), jpeg.size());
  EXPECT_EQ(image["crc32"].get<std::uint32_t>(), crc32_z(0, jpeg.data(), jpeg.size()));
  const auto& labels = j["first"]["/pylon_camera_node_label_id/image"];
  EXPECT_EQ(labels["encoding"], "mono8");
  EXPECT_EQ(labels["width"].get<int>(), sequence.camera.width);
  EXPECT_EQ(labels["height"].get<int>(), sequence.camera.height);
  const auto& info = j["first"]["/pylon_camera_node/camera_info"];
  EXPECT_EQ(info["width"].get<int>(), 160);
  EXPECT_EQ(info["distortion_model"], "plumb_bob");
  EXPECT_EQ(info["k"][0].get<double>(), sequence.camera.fx);
  EXPECT_EQ(info["k"][5].get<double>(), sequence.camera.cy);

  // The first ground-truth pose and the extrinsics.
  const Pose pose = *sequence.poses.at(sequence.scans.front().stamp);
  const auto& odom = j["first"]["/ground_truth/odom"];
  EXPECT_EQ(odom["frame_id"], "map");
  EXPECT_EQ(odom["child_frame_id"], "os1_sensor");
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(odom["position"][i].get<double>(), pose.translation()[i], 1e-12);
  const auto& q = odom["orientation"];
  const Eigen::Quaterniond read(q[3].get<double>(), q[0].get<double>(), q[1].get<double>(), q[2].get<double>());
  EXPECT_NEAR(read.angularDistance(Eigen::Quaterniond(pose.rotation())), 0.0, 1e-9);
  const auto& tf = j["first"]["/tf_static"]["transforms"][0];
  EXPECT_EQ(tf["parent"], "os1_sensor");
  EXPECT_EQ(tf["child"], "pylon_camera");
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(tf["translation"][i].get<double>(), sequence.T_lidar_camera.translation()[i], 1e-12);
}

TEST_F(McapExport, MapOfTheRecordingIsTheMapOfTheFolder) {
  const fs::path from_folder = dir() / "folder.svdb", from_mcap = dir() / "mcap.svdb";
  auto r = slamvdb("map " + quote_path(seq()) + " -o " + quote_path(from_folder) + " --features none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = slamvdb("map " + quote_path(mcap()) + " -o " + quote_path(from_mcap) + " --features none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Topics, extrinsics and poses are taken without options.
  EXPECT_NE(r.output.find("T_lidar_camera from tf (os1_sensor -> pylon_camera)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("/ground_truth/odom"), std::string::npos) << r.output;
  const auto folder_voxels = testing::occupied_voxels(from_folder);
  EXPECT_GT(folder_voxels.size(), 1000u);
  EXPECT_TRUE(testing::occupied_voxels(from_mcap) == folder_voxels);
}

TEST_F(McapExport, ConvertWritesTheSameBytesEveryTime) {
  const fs::path a = dir() / "a.mcap", b = dir() / "b.mcap", none = dir() / "none.mcap";
  auto r = slamvdb("convert " + quote_path(seq()) + " -o " + quote_path(a));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = slamvdb("convert " + quote_path(seq()) + " -o " + quote_path(b));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(bytes_of(a) == bytes_of(b));
  EXPECT_TRUE(bytes_of(a) == bytes_of(mcap()));  // synth --format mcap writes what convert writes
  // Uncompressed small chunks: more chunks, read as well by the independent reader.
  r = slamvdb("convert " + quote_path(seq()) + " -o " + quote_path(none) + " --compression none --chunk-size 0.2");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json compressed = independent_read(a), uncompressed = independent_read(none);
  ASSERT_TRUE(uncompressed.contains("topics")) << uncompressed.dump();
  EXPECT_EQ(uncompressed["topics"], compressed["topics"]);
  EXPECT_GT(uncompressed["chunks"].get<int>(), compressed["chunks"].get<int>());
  EXPECT_GT(fs::file_size(none), fs::file_size(a));
}

TEST_F(McapExport, ConvertUsageAndInputErrors) {
  // Usage errors (exit 2), before any work.
  auto r = slamvdb("convert " + quote_path(seq()) + " -o " + quote_path(dir() / "x.mcap") + " --compression lz4");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = slamvdb("convert " + quote_path(mcap()) + " -o " + quote_path(dir() / "x.mcap"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = slamvdb("convert " + quote_path(seq()));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = slamvdb("synth " + quote_path(dir() / "never") + " --compression none");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--format mcap"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir() / "never"));
  // A folder that is no dataset: a runtime error naming it, and no output.
  fs::create_directories(dir() / "empty");
  r = slamvdb("convert " + quote_path(dir() / "empty") + " -o " + quote_path(dir() / "x.mcap"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("empty"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir() / "x.mcap"));
}

}  // namespace mcap_export_test
}  // namespace slamvdb
