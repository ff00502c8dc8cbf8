// Which container a path is (by content, not by name), the type-name normalisation every
// container uses, and the CRC-32 the MCAP reader checks chunks with.
#include <gtest/gtest.h>
#include <zlib.h>

#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/crc32.hpp"
#include "slamvdb/recording/recording.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"

namespace slamvdb::recording {
namespace {

namespace fs = std::filesystem;

class RecordingDispatch : public testing::RecordingFixtureTest {};

TEST_F(RecordingDispatch, RecordingsAreKnownByTheirContentNotTheirName) {
  const fs::path mcap = write("write_mcap.mjs", "drive.mcap", "--compression lz4");
  const fs::path bag = write("write_rosbag2.mjs", "drive_bag", "--split 2");
  // Renamed: still known by their first bytes.
  fs::rename(mcap, dir() / "drive.data");
  fs::copy_file(bag / "drive_bag_0.db3", dir() / "lone.bin");
  std::ofstream(dir() / "ros1.bag") << "#ROSBAG V2.0\n" << std::string(100, '\0');
  std::ofstream(dir() / "text.mcap") << "not a recording at all";
  fs::create_directories(dir() / "folder");

  EXPECT_TRUE(is_recording(dir() / "drive.data"));
  EXPECT_TRUE(is_recording(bag));
  EXPECT_TRUE(is_recording(dir() / "lone.bin"));
  EXPECT_TRUE(is_recording(dir() / "ros1.bag"));
  EXPECT_FALSE(is_recording(dir() / "text.mcap"));
  EXPECT_FALSE(is_recording(dir() / "folder"));
  EXPECT_FALSE(is_recording(dir() / "seq"));  // a dataset folder
  EXPECT_FALSE(is_recording(dir() / "missing.mcap"));

  EXPECT_EQ(open_recording(dir() / "drive.data")->describe().rfind("MCAP", 0), 0u);
  EXPECT_EQ(open_recording(bag)->describe().rfind("ROS 2 bag (sqlite3 storage, 2 files", 0), 0u)
      << open_recording(bag)->describe();
  EXPECT_EQ(open_recording(dir() / "lone.bin")->describe().rfind("ROS 2 bag (a single", 0), 0u);

  const std::string not_one = testing::error_of([&] { open_recording(dir() / "text.mcap"); });
  EXPECT_NE(not_one.find("text.mcap"), std::string::npos) << not_one;
  EXPECT_NE(not_one.find("none of the recordings"), std::string::npos) << not_one;
  EXPECT_NE(testing::error_of([&] { open_recording(dir() / "missing.mcap"); }).find("does not exist"), std::string::npos);
  EXPECT_NE(testing::error_of([&] { open_recording(dir() / "folder"); }).find("without metadata.yaml"),
            std::string::npos);
}

TEST(RecordingTypeNames, Ros2NamesAreNormalisedToRos1Form) {
  EXPECT_EQ(ros1_type_name("sensor_msgs/msg/PointCloud2"), "sensor_msgs/PointCloud2");
  EXPECT_EQ(ros1_type_name("sensor_msgs::msg::PointCloud2"), "sensor_msgs/PointCloud2");
  EXPECT_EQ(ros1_type_name("sensor_msgs/PointCloud2"), "sensor_msgs/PointCloud2");
  EXPECT_EQ(ros1_type_name("tf2_msgs/msg/TFMessage"), "tf2_msgs/TFMessage");
  EXPECT_EQ(ros1_type_name("foxglove.PointCloud"), "foxglove.PointCloud");  // protobuf: unchanged
  EXPECT_EQ(ros1_type_name("my_pkg/srv/Thing"), "my_pkg/srv/Thing");
  EXPECT_EQ(ros1_type_name("/msg/x"), "/msg/x");
}

TEST(RecordingCrc32, MatchesZlibForAnyLengthAlignmentAndSplit) {
  std::mt19937 rng(3);
  std::vector<unsigned char> bytes(70000);
  for (auto& b : bytes) b = static_cast<unsigned char>(rng());
  for (std::size_t length : {0, 1, 15, 16, 63, 64, 65, 127, 128, 1000, 4099, 65536, 69000}) {
    for (std::size_t offset : {0, 1, 7, 13}) {
      if (offset + length > bytes.size()) continue;
      const auto expected = static_cast<std::uint32_t>(crc32_z(0, bytes.data() + offset, length));
      EXPECT_EQ(crc32(0, bytes.data() + offset, length), expected) << length << " at " << offset;
      const std::size_t half = length / 3;
      EXPECT_EQ(crc32(crc32(0, bytes.data() + offset, half), bytes.data() + offset + half, length - half), expected);
    }
  }
}

}  // namespace
}  // namespace slamvdb::recording
