#pragma once
// A recorded (or synthetic) sequence as the mapping pipeline consumes it, whatever its layout.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/fusion/trajectory.hpp"

namespace slamvdb {

// Largest camera or label image decoded unless configured otherwise (ReadOptions::max_image_pixels,
// `slamvdb map --max-image-pixels`): 100 megapixels, 40x RELLIS-3D's 2.3 MP camera. A 3-channel
// image of that size takes 300 MB once decoded.
inline constexpr std::int64_t kDefaultMaxImagePixels = 100'000'000;

struct ScanRecord {
  double stamp = 0.0;
  std::filesystem::path points;  // x y z intensity float32
  std::filesystem::path labels;  // uint32 per point, low 16 bits class; may be empty
};

// An image carried in memory (from a recording) instead of a file: encoded PNG / JPEG bytes
// (channels 0), decoded where the record is loaded (the inference thread), or raw pixels in rows
// of width x channels bytes (RGB for a camera, class ids for labels).
struct ImageBytes {
  std::vector<std::uint8_t> data;
  int width = 0, height = 0, channels = 0;
  std::string name;  // for messages: "TOPIC message N"
};

struct ImageRecord {
  double stamp = 0.0;
  std::filesystem::path rgb;       // may be empty
  std::filesystem::path labels;    // 2D label image (uint8 ids); may be empty
  std::filesystem::path features;  // precomputed C x H x W .npy; may be empty
  std::filesystem::path view{};    // SIMULATED view geometry (synth's pylon_camera_node_sim_view); usually empty
  // The size the rgb and label images must have (the camera's, which the calibration refers to);
  // set by the sequence readers, checked from the file header before decoding. 0: not checked.
  int width = 0, height = 0;
  // In place of rgb / labels: the image in memory (recordings). Shared: records are copied into queues.
  std::shared_ptr<const ImageBytes> rgb_data{}, label_data{};
  // The camera in the LiDAR frame at this image's stamp, when the extrinsics move (a recording's
  // tf); empty: the sequence's T_lidar_camera.
  std::optional<Pose> T_lidar_camera{};
  bool has_rgb() const { return !rgb.empty() || rgb_data; }
  bool has_labels() const { return !labels.empty() || label_data; }
};

struct Sequence {
  std::filesystem::path root;
  std::string layout;              // "rellis3d" or "kitti"
  CameraModel camera;              // at full image resolution
  Pose T_lidar_camera = Pose::Identity();
  std::vector<ScanRecord> scans;   // sorted by stamp
  std::vector<ImageRecord> images; // sorted by stamp
  Trajectory poses;                // ground-truth T_world_lidar at the scan stamps (may be empty)
  std::vector<std::string> notes;  // assumptions made while reading (e.g. how scan stamps were derived)
};

}  // namespace slamvdb
