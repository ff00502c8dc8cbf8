#include "slamvdb/sensors/mcap_export.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/recording/cdr_encode.hpp"
#include "slamvdb/recording/mcap_writer.hpp"
#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb {

namespace mcap_export_cpp {

using recording::Header;

// The topics and frames of RELLIS-3D's bags (and of tests/recording_fixtures).
constexpr const char* kLidarTopic = "/os1_cloud_node/points";
constexpr const char* kImageTopic = "/pylon_camera_node/image_raw/compressed";
constexpr const char* kCameraInfoTopic = "/pylon_camera_node/camera_info";
constexpr const char* kLabelTopic = "/pylon_camera_node_label_id/image";
constexpr const char* kTfStaticTopic = "/tf_static";
constexpr const char* kOdometryTopic = "/ground_truth/odom";
constexpr const char* kLidarFrame = "os1_sensor";
constexpr const char* kCameraFrame = "pylon_camera";
constexpr const char* kWorldFrame = "map";

// The folder reader's double, back from ns as the recording reader computes it (whole + fraction).
double seconds_from_ns(std::int64_t ns) {
  return static_cast<double>(ns / 1'000'000'000) + static_cast<double>(ns % 1'000'000'000) / 1e9;
}

std::vector<std::uint8_t> file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.good() && !in.eof()) throw Error(fmt::format("cannot read {}", path));
  if (bytes.size() > kMaxImageFileBytes)
    throw Error(fmt::format("{} is larger than {} bytes", path, kMaxImageFileBytes));
  return bytes;
}

// "jpeg" or "png", from the file's first bytes (the format CompressedImage names).
std::string image_format(const std::vector<std::uint8_t>& bytes, const std::filesystem::path& path) {
  if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) return "jpeg";
  if (bytes.size() >= 8 && bytes[0] == 0x89 && bytes[1] == 'P' && bytes[2] == 'N' && bytes[3] == 'G') return "png";
  throw Error(fmt::format("{} is neither a JPEG nor a PNG image", path));
}

class Channels {
 public:
  explicit Channels(recording::mcap::McapWriter& writer) : writer_(writer) {}
  // The channel of `topic` (registered with its schema at its first message).
  std::uint16_t of(const std::string& topic, const std::string& type) {
    auto it = ids_.find(topic);
    if (it != ids_.end()) return it->second;
    auto schema = schemas_.find(type);
    if (schema == schemas_.end())
      schema = schemas_.emplace(type, writer_.add_schema(type, "ros2msg", recording::ros2_definition(type))).first;
    // rosbag2 writes the QoS profiles; an empty value is what `ros2 bag` accepts as "default".
    return ids_[topic] = writer_.add_channel(schema->second, topic, "cdr", {{"offered_qos_profiles", ""}});
  }

 private:
  recording::mcap::McapWriter& writer_;
  std::map<std::string, std::uint16_t> schemas_, ids_;
};

}  // namespace mcap_export_cpp

std::int64_t stamp_to_ns(double seconds) {
  using mcap_export_cpp::seconds_from_ns;
  if (!std::isfinite(seconds) || seconds < 0 || seconds > 9.2e9)
    throw Error(
        fmt::format("time stamp {} s cannot be written to a recording (0 to 9.2e9 s since the epoch)", seconds));
  const double whole = std::floor(seconds);
  const auto whole_ns = static_cast<std::int64_t>(whole) * 1'000'000'000;
  const auto micro = whole_ns + std::llround((seconds - whole) * 1e6) * 1000;
  if (seconds_from_ns(micro) == seconds) return micro;
  return whole_ns + std::llround((seconds - whole) * 1e9);
}

McapExportSummary write_sequence_mcap(const Sequence& sequence, const std::filesystem::path& out,
                                      const McapExportOptions& options,
                                      const std::function<void(std::size_t, std::size_t)>& progress) {
  using namespace mcap_export_cpp;
  recording::mcap::WriterOptions writer_options;
  writer_options.compression = options.compression;
  writer_options.chunk_size = options.chunk_size;
  recording::mcap::McapWriter writer(out, writer_options);
  Channels channels(writer);
  McapExportSummary summary;
  const auto put = [&](const char* topic, const char* type, std::int64_t stamp_ns,
                       const std::vector<std::uint8_t>& data) {
    const auto t = static_cast<std::uint64_t>(stamp_ns);
    writer.write(channels.of(topic, type), t, t, data);
    ++summary.messages[topic];
  };
  const auto header = [](double stamp, const char* frame) { return Header{0, stamp_to_ns(stamp), frame}; };

  const auto& scans = sequence.scans;
  const auto& images = sequence.images;
  const bool with_camera = !images.empty() && sequence.camera.width > 0;
  const std::size_t total = scans.size() + (with_camera ? images.size() : 0);
  if (total == 0) throw Error(fmt::format("{} has no scans to write", sequence.root));

  // T_lidar_camera once, at the first stamp.
  if (with_camera) {
    const double first = std::min(scans.empty() ? images.front().stamp : scans.front().stamp, images.front().stamp);
    recording::TransformStamped tf;
    tf.header = header(first, kLidarFrame);
    tf.child_frame_id = kCameraFrame;
    tf.T_parent_child = sequence.T_lidar_camera;
    put(kTfStaticTopic, "tf2_msgs/msg/TFMessage", tf.header.stamp_ns, recording::encode_tf_message({&tf, 1}));
  }
  recording::CameraInfo info;
  if (with_camera) {
    const CameraModel& c = sequence.camera;
    info.width = static_cast<std::uint32_t>(c.width);
    info.height = static_cast<std::uint32_t>(c.height);
    info.distortion_model = "plumb_bob";
    info.D.assign(c.distortion.begin(), c.distortion.end());
    info.K = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
    info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    info.P = {c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0};
  }

  std::size_t s = 0, i = 0;
  while (s < scans.size() || (with_camera && i < images.size())) {
    // A scan before an image of the same stamp, as the readers deliver them.
    if (s < scans.size() && (!with_camera || i >= images.size() || scans[s].stamp <= images[i].stamp)) {
      const ScanRecord& record = scans[s++];
      const LidarScan scan = read_scan({record.stamp, record.points, {}});
      const Header h = header(record.stamp, kLidarFrame);
      put(kLidarTopic, "sensor_msgs/msg/PointCloud2", h.stamp_ns,
          recording::encode_point_cloud2(h, scan.points, scan.intensity, {}));
      if (const std::optional<Pose> pose = sequence.poses.empty() ? std::nullopt : sequence.poses.at(record.stamp)) {
        recording::Odometry odom;
        odom.header = header(record.stamp, kWorldFrame);
        odom.child_frame_id = kLidarFrame;
        odom.T_frame_child = *pose;
        put(kOdometryTopic, "nav_msgs/msg/Odometry", h.stamp_ns, recording::encode_odometry(odom));
      }
    } else {
      const ImageRecord& record = images[i++];
      if (!record.rgb.empty()) {
        const auto bytes = file_bytes(record.rgb);
        const Header h = header(record.stamp, kCameraFrame);
        put(kImageTopic, "sensor_msgs/msg/CompressedImage", h.stamp_ns,
            recording::encode_compressed_image(h, image_format(bytes, record.rgb), bytes));
        info.header = h;
        put(kCameraInfoTopic, "sensor_msgs/msg/CameraInfo", h.stamp_ns, recording::encode_camera_info(info));
      }
      if (!record.labels.empty()) {
        ImageRecord labels_only;  // the label PNG alone (not the SIMULATED view geometry beside it)
        labels_only.labels = record.labels;
        labels_only.width = record.width;
        labels_only.height = record.height;
        const ImageFrame frame = load_image_frame(labels_only, false, true);
        const cv::Mat& ids = frame.labels;
        const Header h = header(record.stamp, kCameraFrame);
        std::vector<std::uint8_t> pixels(static_cast<std::size_t>(ids.total()));
        for (int row = 0; row < ids.rows; ++row)
          std::memcpy(pixels.data() + static_cast<std::size_t>(row) * ids.cols, ids.ptr<std::uint8_t>(row),
                      static_cast<std::size_t>(ids.cols));
        put(kLabelTopic, "sensor_msgs/msg/Image", h.stamp_ns,
            recording::encode_mono8_image(h, static_cast<std::uint32_t>(ids.cols), static_cast<std::uint32_t>(ids.rows),
                                          pixels));
      }
    }
    if (progress) progress(s + (with_camera ? i : 0), total);
  }
  const recording::mcap::WriterStats stats = writer.finish();
  summary.bytes = stats.bytes;
  summary.uncompressed_bytes = stats.uncompressed_bytes;
  summary.chunks = stats.chunks;
  return summary;
}

std::size_t compare_recording_scans(const Sequence& sequence, const std::filesystem::path& recording) {
  const std::unique_ptr<SensorInput> input = open_sensor_input(recording, InputOptions{});
  const std::unique_ptr<SensorStream> stream = input->open(false);
  SensorFrame frame;
  std::size_t n = 0;
  while (stream->next(frame)) {
    if (frame.kind != SensorFrame::Kind::kScan) continue;
    if (n >= sequence.scans.size())
      throw Error(fmt::format("{} holds more scans than {} ({})", recording, sequence.root, sequence.scans.size()));
    const ScanRecord& record = sequence.scans[n];
    const LidarScan scan = read_scan(record);
    if (!frame.error.empty()) throw Error(fmt::format("{}: {}: {}", recording, frame.name, frame.error));
    if (frame.stamp != record.stamp || frame.points.size() != scan.points.size() ||
        (!scan.points.empty() &&
         std::memcmp(frame.points.data(), scan.points.data(), scan.points.size() * sizeof(Vec3f)) != 0))
      throw Error(fmt::format("{}: {} differs from {} (stamp {:.6f} vs {:.6f}, {} vs {} points)", recording, frame.name,
                              record.points, frame.stamp, record.stamp, frame.points.size(), scan.points.size()));
    ++n;
  }
  if (n != sequence.scans.size())
    throw Error(fmt::format("{} holds {} scans, {} has {}", recording, n, sequence.root, sequence.scans.size()));
  return n;
}

}  // namespace slamvdb
