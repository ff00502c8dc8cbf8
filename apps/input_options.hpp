#pragma once
// The input of the mapping commands (map, slam, odometry): a dataset folder or a robot recording
// (sensors/sensor_input.hpp), with the options that choose a recording's topics, extrinsics and
// time source, and the progress text for recordings (messages/s, MB/s).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <memory>
#include <string>

#include "option_checks.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb::cli {

struct RecordingOptions {
  TopicChoice topics;
  std::string extrinsics, time_source = "header", pose_frame, sensor_frame;
  bool skip_bad_messages = false;

  void add_to(CLI::App* cmd) {
    cmd->add_option("--lidar-topic", topics.lidar, "Recordings: the sensor_msgs/PointCloud2 topic (default: the only one)");
    cmd->add_option("--image-topic", topics.image,
                    "Recordings: the camera's Image or CompressedImage topic (default: the only image topic with a "
                    "CameraInfo in its namespace)");
    cmd->add_option("--camera-info-topic", topics.camera_info,
                    "Recordings: the camera's CameraInfo topic (default: the one in the image topic's namespace)");
    cmd->add_option("--label-topic", topics.labels,
                    "Recordings: SIMULATED label images (sensor_msgs/Image mono8) for --features simulated (default: "
                    "the only image topic named 'label')");
    cmd->add_option("--pose-topic", topics.poses,
                    "Recordings: poses of the LiDAR from a nav_msgs/Odometry, geometry_msgs/PoseStamped or "
                    "TransformStamped topic (map: default the only such topic)");
    cmd->add_option("--pose-frame", pose_frame,
                    "Recordings: poses from tf, T_F_S of this frame F (e.g. map or odom) and --sensor-frame S at "
                    "each scan's stamp, instead of a pose topic");
    cmd->add_option("--sensor-frame", sensor_frame,
                    "Recordings, with --pose-frame: the sensor's frame in tf (default: the LiDAR messages' frame_id)");
    cmd->add_option("--extrinsics", extrinsics,
                    "Recordings: T_lidar_camera from a RELLIS transforms.yaml, for recordings without the transform in "
                    "/tf_static or /tf (given, it is used instead of tf's)")
        ->check(CLI::ExistingFile);
    cmd->add_option("--time-source", time_source,
                    "Recordings: stamps from the message headers ('header') or the record times ('log')")
        ->capture_default_str()
        ->check(CLI::IsMember({"header", "log"}));
    cmd->add_flag("--skip-bad-messages", skip_bad_messages,
                  "Recordings: skip and count messages of a known type that do not decode, instead of stopping");
  }

  // Usage errors (exit 2) for options that exclude each other.
  InputOptions input_options() const {
    if (!pose_frame.empty() && !topics.poses.empty())
      usage_error("--pose-frame and --pose-topic are two pose sources: give one");
    if (!sensor_frame.empty() && pose_frame.empty()) usage_error("--sensor-frame goes with --pose-frame");
    InputOptions o;
    o.pose_frame = pose_frame;
    o.sensor_frame = sensor_frame;
    o.topics = topics;
    o.extrinsics = extrinsics;
    o.time_source = time_source == "log" ? TimeSource::kLog : TimeSource::kHeader;
    o.skip_bad_messages = skip_bad_messages;
    return o;
  }
};

// Opens the input; a topic choice only the user can make is a usage error (exit 2).
inline std::unique_ptr<SensorInput> open_input(const std::string& path, const InputOptions& options) {
  try {
    return open_sensor_input(path, options);
  } catch (const TopicChoiceError& e) {
    usage_error(fmt::format("{}: {}", path, e.what()));
  }
}

// What the command prints about its input before the work.
inline void print_input(const SensorInput& input) {
  const Sequence& seq = input.sequence();
  if (input.is_recording()) {
    fmt::print("recording {} ({}): {} scans{}\n", seq.root.string(), input.kind(),
               input.scan_count() ? std::to_string(input.scan_count()) : "an unknown number of",
               input.has_camera() ? "" : ", no camera");
  } else {
    fmt::print("sequence {} ({} layout): {} scans, {} images\n", seq.root.string(), input.kind(), seq.scans.size(),
               seq.images.size());
  }
  for (const auto& note : seq.notes) fmt::print("  note: {}\n", escape_control(note));
}

// Progress text for a recording: messages and megabytes per second since `start`.
inline std::string read_rate(const StreamProgress& read, std::chrono::steady_clock::time_point start) {
  if (read.bytes_total == 0) return {};
  const double t = std::max(1e-9, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return fmt::format("{:.0f} msg/s, {:.1f} MB/s, {:.0f}% read", read.messages / t, read.bytes_read / t / 1e6,
                     100.0 * read.bytes_read / read.bytes_total);
}

}  // namespace slamvdb::cli
