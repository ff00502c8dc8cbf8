#pragma once
// A dataset folder (RELLIS-3D or KITTI layout, e.g. what `slamvdb synth` writes) as a ROS 2 MCAP
// recording, for `slamvdb convert` and `slamvdb synth --format mcap`: users open the drive in
// Foxglove or RViz, and slamvdb's commands read it back as they read the folder (the same map).
//
//   /os1_cloud_node/points                  sensor_msgs/PointCloud2 (x y z intensity float32, t uint32)
//   /pylon_camera_node/image_raw/compressed sensor_msgs/CompressedImage (the image file's bytes, jpeg or png)
//   /pylon_camera_node/camera_info          sensor_msgs/CameraInfo (plumb_bob), one per image
//   /pylon_camera_node_label_id/image       sensor_msgs/Image mono8 (the label images, when the folder has them)
//   /tf_static                              tf2_msgs/TFMessage: T_lidar_camera (os1_sensor -> pylon_camera)
//   /ground_truth/odom                      nav_msgs/Odometry, map -> os1_sensor, one per scan (when poses exist)
//
// The topic names, frames and layouts are those of RELLIS-3D's own bags and of the test fixtures
// (tests/recording_fixtures), so slamvdb chooses the topics without options. Per-point `t` is ns
// since the scan's stamp; the folders hold no per-point times (KITTI .bin has none), so t = 0 for
// every point. Messages are written in stamp order (a scan before an image of the same stamp);
// log time = header stamp.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

struct McapExportOptions {
  std::string compression = "zstd";  // or "" for uncompressed chunks
  std::uint64_t chunk_size = std::uint64_t{4} << 20;
};

struct McapExportSummary {
  std::map<std::string, std::uint64_t> messages;  // per topic
  std::uint64_t bytes = 0, uncompressed_bytes = 0, chunks = 0;
};

// Writes `sequence` (read_sequence) to `out`; `progress(done, total)` counts scans and images.
// Throws Error naming the file that cannot be read, or the output that cannot be written (the
// output is then left as it was).
McapExportSummary write_sequence_mcap(const Sequence& sequence, const std::filesystem::path& out,
                                      const McapExportOptions& options = {},
                                      const std::function<void(std::size_t, std::size_t)>& progress = {});

// Reads the scans of `recording` back through the recording input (the path `map` takes) and
// compares them with `sequence`'s files: the same number, stamps and points, bit for bit. Throws
// Error naming the first scan that differs; returns the scans compared. The demo checks its
// drive.mcap with it.
std::size_t compare_recording_scans(const Sequence& sequence, const std::filesystem::path& recording);

// Seconds since the epoch -> ns, rounded to the microsecond when that gives back the same double
// (stamps parsed from text such as times.txt), so that the recording carries 1700000000.100000000
// rather than the double's 1700000000.099999905.
std::int64_t stamp_to_ns(double seconds);

}  // namespace slamvdb
