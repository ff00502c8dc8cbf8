// slamvdb's MCAP writer and CDR encoders, read back by slamvdb's own reader and decoders (the
// independent check, @mcap/core and @foxglove's CDR reader, is sensors/mcap_export_test.cpp):
// several chunks with their indexes, zstd and uncompressed, messages and times as written, the
// summary's counts, and the messages decoding to what was encoded.
#include "slamvdb/recording/mcap_writer.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/cdr_encode.hpp"
#include "slamvdb/recording/image.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/point_cloud2.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::recording {
// Named, not anonymous: the unity build merges test files.
namespace mcap_writer_test {

namespace fs = std::filesystem;

// 40 messages on two channels, chunks of about 1 kB: several chunks, each message read back.
void write_and_read_back(const std::string& compression) {
  testing::TempDir tmp;
  const fs::path file = tmp.path / "out.mcap";
  mcap::WriterOptions options;
  options.compression = compression;
  options.chunk_size = 1000;
  mcap::McapWriter writer(file, options);
  const auto cloud_schema =
      writer.add_schema("sensor_msgs/msg/PointCloud2", "ros2msg", ros2_definition("sensor_msgs/msg/PointCloud2"));
  const auto odom_schema =
      writer.add_schema("nav_msgs/msg/Odometry", "ros2msg", ros2_definition("nav_msgs/msg/Odometry"));
  const auto clouds = writer.add_channel(cloud_schema, "/points", "cdr");
  const auto odoms = writer.add_channel(odom_schema, "/odom", "cdr");
  std::vector<std::vector<std::uint8_t>> written;
  for (int i = 0; i < 20; ++i) {
    const std::int64_t stamp = 1'700'000'000'000'000'000 + i * 100'000'000LL + 7;
    const std::vector<Vec3f> points = {{1.f * i, 2.f, 3.f}, {4.f, 5.f, -6.f * i}};
    const std::vector<float> intensity = {0.5f, 0.25f};
    const std::vector<std::uint32_t> t = {0, static_cast<std::uint32_t>(1000 * i)};
    written.push_back(encode_point_cloud2({0, stamp, "lidar"}, points, intensity, t));
    writer.write(clouds, static_cast<std::uint64_t>(stamp), static_cast<std::uint64_t>(stamp), written.back());
    Odometry odom;
    odom.header = {0, stamp, "map"};
    odom.child_frame_id = "lidar";
    odom.T_frame_child = Pose(Eigen::AngleAxisd(0.1 * i, Vec3d::UnitZ()));
    odom.T_frame_child.translation() = Vec3d(i, -i, 0.5);
    written.push_back(encode_odometry(odom));
    writer.write(odoms, static_cast<std::uint64_t>(stamp), static_cast<std::uint64_t>(stamp), written.back());
  }
  const mcap::WriterStats stats = writer.finish();
  EXPECT_EQ(stats.messages, 40u);
  EXPECT_GT(stats.chunks, 3u);
  EXPECT_EQ(stats.bytes, fs::file_size(file));

  const auto reader = open_mcap(file);
  EXPECT_NE(reader->describe().find("ros2"), std::string::npos) << reader->describe();
  ASSERT_EQ(reader->channels().size(), 2u);
  for (const Channel& c : reader->channels()) {
    ASSERT_TRUE(c.message_count.has_value());
    EXPECT_EQ(*c.message_count, 20u) << c.topic;  // from the summary's statistics
    EXPECT_EQ(c.serialization, Serialization::kCdr);
  }
  ASSERT_TRUE(reader->time_range().has_value());
  EXPECT_EQ(reader->time_range()->start_ns, 1'700'000'000'000'000'007);
  EXPECT_EQ(reader->time_range()->end_ns, 1'700'000'001'900'000'007);
  Message m;
  std::size_t n = 0;
  while (reader->next(m)) {
    ASSERT_LT(n, written.size());
    EXPECT_EQ(std::vector<std::uint8_t>(m.data.begin(), m.data.end()), written[n]) << "message " << n;
    const int i = static_cast<int>(n / 2);
    if (n % 2 == 0) {
      EXPECT_EQ(m.channel->type, "sensor_msgs/PointCloud2");
      const PointCloud2View cloud = decode_point_cloud2(m.data, Serialization::kCdr);
      EXPECT_EQ(cloud.header.stamp_ns, m.log_time_ns);
      EXPECT_EQ(cloud.header.frame_id, "lidar");
      EXPECT_EQ(cloud.point_count(), 2u);
      ASSERT_NE(cloud.field("t"), nullptr);
      EXPECT_EQ(cloud.field("t")->datatype, 6);
    } else {
      const Odometry odom = decode_odometry(m.data, Serialization::kCdr);
      EXPECT_EQ(odom.child_frame_id, "lidar");
      EXPECT_TRUE(odom.T_frame_child.translation().isApprox(Vec3d(i, -i, 0.5)));
      EXPECT_NEAR(Eigen::AngleAxisd(odom.T_frame_child.rotation()).angle(), 0.1 * i, 1e-12);
    }
    ++n;
  }
  EXPECT_EQ(n, written.size());
}

TEST(McapWriter, ZstdChunksReadBackMessageForMessage) { write_and_read_back("zstd"); }
TEST(McapWriter, UncompressedChunksReadBackMessageForMessage) { write_and_read_back(""); }

TEST(McapWriter, MessagesDecodeToWhatWasEncoded) {
  const std::vector<Vec3f> points = {{1.5f, -2.f, 0.25f}, {3.f, 4.f, 5.f}, {-1.f, 0.f, 7.f}};
  const std::vector<std::uint32_t> t = {0, 50'000, 99'000'000};
  const auto bytes = encode_point_cloud2({0, 12'000'000'034, "os"}, points, {}, t);
  const PointCloud2View cloud = decode_point_cloud2(bytes, Serialization::kCdr);
  EXPECT_EQ(cloud.header.stamp_ns, 12'000'000'034);
  EXPECT_EQ(cloud.point_step, 16u);  // x y z t: no intensity given
  EXPECT_EQ(cloud.field("intensity"), nullptr);
  const auto x = cloud.field("x");
  ASSERT_NE(x, nullptr);
  float second_x = 0;
  std::memcpy(&second_x, cloud.data.data() + cloud.point_step + x->offset, 4);
  EXPECT_EQ(second_x, 3.f);
  std::uint32_t last_t = 0;
  std::memcpy(&last_t, cloud.data.data() + 2 * cloud.point_step + cloud.field("t")->offset, 4);
  EXPECT_EQ(last_t, 99'000'000u);

  const std::vector<std::uint8_t> pixels = {1, 2, 3, 4, 5, 6};
  // The views point into the message bytes, which must outlive them.
  const auto image_bytes = encode_mono8_image({0, 5, "cam"}, 3, 2, pixels);
  const ImageView image = decode_image(image_bytes, Serialization::kCdr);
  std::vector<std::uint8_t> mono;
  image_to_mono8(image, mono);
  EXPECT_EQ(mono, pixels);
  EXPECT_EQ(image.encoding, "mono8");

  const std::vector<std::uint8_t> jpeg = {0xFF, 0xD8, 0xFF, 0xE0};
  const auto compressed_bytes = encode_compressed_image({0, 5, "cam"}, "jpeg", jpeg);
  const CompressedImageView compressed = decode_compressed_image(compressed_bytes, Serialization::kCdr);
  EXPECT_EQ(compressed.format, "jpeg");
  EXPECT_EQ(std::vector<std::uint8_t>(compressed.data.begin(), compressed.data.end()), jpeg);

  CameraInfo info;
  info.header = {0, 9, "cam"};
  info.width = 640;
  info.height = 400;
  info.distortion_model = "plumb_bob";
  info.D = {0.1, -0.2, 0.001, 0.002, 0};
  info.K = {500, 0, 320, 0, 501, 200, 0, 0, 1};
  const CameraInfo back = decode_camera_info(encode_camera_info(info), Serialization::kCdr);
  EXPECT_EQ(back.D, info.D);
  EXPECT_EQ(back.K, info.K);
  EXPECT_EQ(back.width, 640u);
  EXPECT_EQ(back.distortion_model, "plumb_bob");

  TransformStamped tf;
  tf.header = {0, 9, "os1_sensor"};
  tf.child_frame_id = "pylon_camera";
  tf.T_parent_child = Pose(Eigen::AngleAxisd(1.0, Vec3d(1, 2, 3).normalized()));
  tf.T_parent_child.translation() = Vec3d(0.1, -0.2, 0.3);
  const auto tfs = decode_tf_message(encode_tf_message({&tf, 1}), Serialization::kCdr);
  ASSERT_EQ(tfs.size(), 1u);
  EXPECT_EQ(tfs[0].child_frame_id, "pylon_camera");
  EXPECT_TRUE(tfs[0].T_parent_child.isApprox(tf.T_parent_child, 1e-12));
}

TEST(McapWriter, BadUseIsAnError) {
  testing::TempDir tmp;
  mcap::WriterOptions lz4;
  lz4.compression = "lz4";
  EXPECT_THROW(mcap::McapWriter(tmp.path / "a.mcap", lz4), Error);
  mcap::McapWriter writer(tmp.path / "b.mcap");
  const std::vector<std::uint8_t> data = {1};
  EXPECT_THROW(writer.write(1, 0, 0, data), Error);         // no such channel
  EXPECT_THROW(writer.add_channel(3, "/x", "cdr"), Error);  // no such schema
  EXPECT_THROW(ros2_definition("std_msgs/msg/String"), Error);
}

TEST(McapWriter, UnfinishedWriterLeavesNoFile) {
  testing::TempDir tmp;
  {
    mcap::McapWriter writer(tmp.path / "c.mcap");
    writer.add_schema("s", "ros2msg", "int32 a");
  }
  EXPECT_FALSE(fs::exists(tmp.path / "c.mcap"));
}

}  // namespace mcap_writer_test
}  // namespace slamvdb::recording
