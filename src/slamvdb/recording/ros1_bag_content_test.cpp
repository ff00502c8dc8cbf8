// A bag written by ROS's own writer and message classes from a simulated sequence, read back and
// decoded: every message equals what the sequence's files hold (scans, poses, images, calibration),
// through the container reader and the decoders together.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/recording/image.hpp"
#include "slamvdb/recording/point_cloud2.hpp"
#include "slamvdb/recording/ros1_bag.hpp"
#include "slamvdb/testing/ros1_bag_fixture.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::recording {
namespace ros1_bag_content_test {

namespace fs = std::filesystem;

std::int64_t seconds_text_to_ns(const std::string& text) {  // as the writer parses times.txt
  const auto dot = text.find('.');
  std::string fraction = dot == std::string::npos ? "" : text.substr(dot + 1);
  fraction = (fraction + "000000000").substr(0, 9);
  return std::stoll(text.substr(0, dot)) * 1'000'000'000 + std::stoll(fraction);
}

std::vector<fs::path> sorted_files(const fs::path& dir, const std::string& extension) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == extension) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

TEST(Ros1BagContent, DecodesToTheSequenceItWasWrittenFrom) {
  testing::TempDir tmp;
  const fs::path sequence = testing::ros1_bag_test_sequence();
  constexpr std::int64_t kLogOffsetNs = -5'184'000'000'000'000;  // log times 60 days before the stamps
  // Per-point times (uint32 ns since the scan start) for every scan, as a driver writes them.
  const auto scans = sorted_files(sequence / "os1_cloud_node_kitti_bin", ".bin");
  const auto point_time_ns = [](std::size_t p) { return static_cast<std::uint32_t>((p % 1024) * 97'000); };
  fs::create_directories(tmp.path / "times");
  for (const fs::path& scan : scans) {
    std::vector<std::uint8_t> times(fs::file_size(scan) / 4);  // 4 bytes per point of 16 (x y z i)
    for (std::size_t p = 0; p < times.size() / 4; ++p) {
      const std::uint32_t t = point_time_ns(p);
      std::memcpy(times.data() + 4 * p, &t, 4);
    }
    testing::write_bytes(tmp.path / "times" / scan.filename(), times);
  }
  const auto bag = testing::write_ros1_bag(tmp.path, "content.bag",
                                           "--compression lz4 --organised 64 --padding 4 --tf-type tf/tfMessage "
                                           "--log-time-offset -5184000 --point-times " +
                                               testing::quote_path(tmp.path / "times"));
  std::vector<std::int64_t> stamps;
  {
    std::ifstream in(sequence / "times.txt");
    for (std::string line; std::getline(in, line);)
      if (!line.empty()) stamps.push_back(seconds_text_to_ns(line));
  }
  std::vector<std::vector<double>> poses;
  {
    std::ifstream in(sequence / "poses.txt");
    for (std::string line; std::getline(in, line);) {
      std::istringstream row(line);
      poses.emplace_back(std::istream_iterator<double>(row), std::istream_iterator<double>());
    }
  }
  const auto jpegs = sorted_files(sequence / "pylon_camera_node", ".jpg");
  const auto labels = sorted_files(sequence / "pylon_camera_node_label_id", ".png");
  ASSERT_EQ(scans.size(), stamps.size());
  ASSERT_FALSE(jpegs.empty());

  const auto reader = open_ros1_bag(bag.path);
  std::map<MessageKind, std::size_t> seen;
  std::vector<Vec3f> points;
  std::vector<float> times, intensity;
  std::vector<std::uint8_t> mono;
  Message m;
  while (reader->next(m)) {
    const MessageKind kind = message_kind(m.channel->type);
    const std::size_t i = seen[kind]++;
    SCOPED_TRACE(m.channel->topic + " #" + std::to_string(i));
    if (kind == MessageKind::kPointCloud2) {
      const PointCloud2View cloud = decode_point_cloud2(m.data, m.channel->serialization);
      EXPECT_EQ(cloud.header.stamp_ns, stamps[i]);
      EXPECT_EQ(m.log_time_ns, stamps[i] + kLogOffsetNs);
      EXPECT_EQ(cloud.header.frame_id, "os1_sensor");
      EXPECT_EQ(cloud.height, 64u);
      EXPECT_EQ(cloud.point_step, 24u);
      const auto bin = testing::file_bytes(scans[i]);
      ASSERT_EQ(cloud.point_count() * 16, bin.size());
      const CloudExtraction result = extract_points(cloud, points, &times, &intensity);
      EXPECT_TRUE(result.fast_path);
      EXPECT_EQ(result.time_field, PointTimeField::kT);
      for (std::size_t p = 0; p < points.size(); ++p) {
        float xyzi[4];
        std::memcpy(xyzi, bin.data() + 16 * p, 16);
        ASSERT_EQ(points[p], Vec3f(xyzi[0], xyzi[1], xyzi[2])) << "point " << p;
        ASSERT_EQ(intensity[p], xyzi[3]);
        ASSERT_EQ(times[p], static_cast<float>(point_time_ns(p) * 1e-9)) << "point " << p;
      }
    } else if (kind == MessageKind::kOdometry) {
      const Odometry odometry = decode_odometry(m.data, m.channel->serialization);
      EXPECT_EQ(odometry.header.stamp_ns, stamps[i]);
      EXPECT_EQ(odometry.header.frame_id, "map");
      EXPECT_EQ(odometry.child_frame_id, "os1_sensor");
      const auto& row = poses[i];
      for (int r = 0; r < 3; ++r) {
        EXPECT_NEAR(odometry.T_frame_child.translation()[r], row[4 * r + 3], 1e-12);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(odometry.T_frame_child.linear()(r, c), row[4 * r + c], 1e-8);
      }
    } else if (kind == MessageKind::kCompressedImage) {
      const CompressedImageView image = decode_compressed_image(m.data, m.channel->serialization);
      EXPECT_EQ(image.format, "jpeg");
      EXPECT_EQ(image.header.frame_id, "pylon_camera");
      EXPECT_EQ(m.log_time_ns, image.header.stamp_ns + kLogOffsetNs);
      const auto jpeg = testing::file_bytes(jpegs.at(i));
      EXPECT_TRUE(std::equal(image.data.begin(), image.data.end(), jpeg.begin(), jpeg.end()));
    } else if (kind == MessageKind::kCameraInfo) {
      const CameraInfo info = decode_camera_info(m.data, m.channel->serialization);
      std::ifstream in(sequence / "camera_info.txt");
      double fx, fy, cx, cy;
      in >> fx >> fy >> cx >> cy;
      std::vector<double> D(5);
      for (double& d : D) in >> d;
      EXPECT_EQ(info.distortion_model, "plumb_bob");
      EXPECT_EQ(info.width, 64u);
      EXPECT_EQ(info.height, 40u);
      EXPECT_EQ(info.D, D);
      EXPECT_EQ(info.K, (std::array<double, 9>{fx, 0, cx, 0, fy, cy, 0, 0, 1}));
      EXPECT_EQ(info.P, (std::array<double, 12>{fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0}));
    } else if (kind == MessageKind::kImage) {
      const ImageView image = decode_image(m.data, m.channel->serialization);
      EXPECT_EQ(image.encoding, "mono8");
      image_to_mono8(image, mono);
      const cv::Mat png = cv::imread(labels.at(i).string(), cv::IMREAD_UNCHANGED);
      ASSERT_EQ(png.type(), CV_8UC1);
      ASSERT_EQ(mono.size(), png.total());
      EXPECT_TRUE(std::equal(mono.begin(), mono.end(), png.data));
    } else if (kind == MessageKind::kTf) {
      EXPECT_EQ(m.channel->type, "tf/tfMessage");
      EXPECT_EQ(m.channel->topic, "/tf_static");
      const auto tf = decode_tf_message(m.data, m.channel->serialization);
      ASSERT_EQ(tf.size(), 1u);
      EXPECT_EQ(tf[0].header.frame_id, "os1_sensor");
      EXPECT_EQ(tf[0].child_frame_id, "pylon_camera");
      const YAML::Node t = YAML::LoadFile((sequence / "transforms.yaml").string()).begin()->second;
      const Eigen::Quaterniond q(t["q"]["w"].as<double>(), t["q"]["x"].as<double>(), t["q"]["y"].as<double>(),
                                 t["q"]["z"].as<double>());
      EXPECT_TRUE(tf[0].T_parent_child.linear().isApprox(q.normalized().toRotationMatrix(), 1e-12));
      EXPECT_NEAR(tf[0].T_parent_child.translation().x(), t["t"]["x"].as<double>(), 1e-15);
    } else {
      ADD_FAILURE() << "unexpected type " << m.channel->type;
    }
  }
  EXPECT_EQ(seen[MessageKind::kPointCloud2], scans.size());
  EXPECT_EQ(seen[MessageKind::kOdometry], scans.size());
  EXPECT_EQ(seen[MessageKind::kCompressedImage], jpegs.size());
  EXPECT_EQ(seen[MessageKind::kCameraInfo], jpegs.size());
  EXPECT_EQ(seen[MessageKind::kImage], labels.size());
  EXPECT_EQ(seen[MessageKind::kTf], 1u);
}

}  // namespace ros1_bag_content_test
}  // namespace slamvdb::recording
