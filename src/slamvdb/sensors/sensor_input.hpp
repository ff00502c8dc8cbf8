#pragma once
// What the mapping commands read, whatever it is: a dataset folder (RELLIS-3D or KITTI layout, or a
// plain folder of scan files) or a robot recording (ROS 1 bag, ROS 2 bag, MCAP). Both give
//   - before the data: the camera, T_lidar_camera, poses (ground truth or a pose topic), notes;
//   - a stream of scans and images in time order (a scan before an image of the same stamp),
//     read as it goes: memory holds the frames in flight, never the whole input.
// Images of a recording stay encoded (or raw pixels) in memory until the inference thread loads
// them (ImageRecord::rgb_data, label_data), as a folder's files are read there.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/types.hpp"
#include "slamvdb/io/dataset.hpp"
#include "slamvdb/io/sequence_reader.hpp"

namespace slamvdb {

struct SensorFrame {
  enum class Kind { kScan, kImage };
  Kind kind = Kind::kScan;
  double stamp = 0.0;
  std::string name;                // the file, or "TOPIC message N", for messages
  std::vector<Vec3f> points;       // kScan, NaN points included (the consumers count them)
  std::vector<float> point_times;  // kScan: per-point seconds relative to `stamp`; empty: none
  std::string error;               // kScan that could not be read: why (points empty)
  ImageRecord image;               // kImage
};

// How far a stream has read (recordings: bytes of the files and messages; folders: 0).
struct StreamProgress {
  std::uint64_t bytes_read = 0, bytes_total = 0, messages = 0;
};

class SensorStream {
 public:
  virtual ~SensorStream() = default;
  // The next frame in time order; false at the end. Throws Error on a damaged recording (naming
  // the topic and message) unless the input skips bad messages.
  virtual bool next(SensorFrame& out) = 0;
  virtual StreamProgress progress() const { return {}; }
  // What was skipped and counted so far, one line each ("3 messages of unknown type X on /t").
  virtual std::vector<std::string> skipped() const { return {}; }
};

// Which topic of a recording is which; empty: chosen automatically (recording_topics.hpp).
struct TopicChoice {
  std::string lidar, image, camera_info, labels, poses;
};

enum class TimeSource { kHeader, kLog };

struct InputOptions {
  ReadOptions read;       // dataset folders (and the image size limit of recordings)
  double rate_hz = 10.0;  // stamps of a plain scan folder without times.txt (scans_only)
  bool scans_only = false;  // `odometry`: a plain folder of .bin / .pcd scans is accepted, images are not read
  TopicChoice topics;
  std::string extrinsics;  // RELLIS transforms.yaml giving T_lidar_camera when a recording has no tf
  TimeSource time_source = TimeSource::kHeader;
  bool skip_bad_messages = false;  // count and skip messages of a known type that do not decode
  bool need_poses = false;  // a pose topic is chosen automatically when there is one (map's ground truth)
  // Poses from tf instead of a pose topic: T_pose_sensor at each scan's stamp (sensor_frame empty:
  // the LiDAR's frame). Frames tf does not know or connect are a TopicChoiceError.
  std::string pose_frame, sensor_frame;
};

class SensorInput {
 public:
  virtual ~SensorInput() = default;
  // Calibration, ground-truth poses and notes. Dataset folders also list their scan and image
  // files here; a recording's `scans` and `images` are empty (they are only streamed).
  const Sequence& sequence() const { return sequence_; }
  // "rellis3d", "kitti", "folder", or the recording's description ("MCAP (ros2, zstd)").
  const std::string& kind() const { return kind_; }
  bool is_recording() const { return recording_; }
  bool has_camera() const { return has_camera_; }
  // Whether the images carry SIMULATED label images (a dataset's label folder, a recording's label topic).
  bool has_labels() const { return has_labels_; }
  // Scans in the input when known before reading (0: unknown).
  std::size_t scan_count() const { return scan_count_; }
  // A new stream from the start (a first pass, e.g. `map --odometry`, and the mapping pass each
  // open one). Without images it reads scans only.
  virtual std::unique_ptr<SensorStream> open(bool with_images) const = 0;

 protected:
  Sequence sequence_;
  std::string kind_;
  bool recording_ = false, has_camera_ = false, has_labels_ = false;
  std::size_t scan_count_ = 0;
};

// A topic choice only the user can make (several candidates of a kind), or a topic option that
// names no fitting topic: the commands report it as a usage error (exit 2).
class TopicChoiceError : public Error {
 public:
  using Error::Error;
};

// A dataset folder already read (tests; the commands use open_sensor_input).
std::unique_ptr<SensorInput> sequence_input(Sequence sequence);

// Opens `path`: a recording (recording::is_recording), a dataset folder, or with
// options.scans_only a plain folder of scan files. Throws Error naming what is missing; a topic
// choice that cannot be made (several candidates) is a UsageError listing them.
std::unique_ptr<SensorInput> open_sensor_input(const std::filesystem::path& path, const InputOptions& options);

}  // namespace slamvdb
