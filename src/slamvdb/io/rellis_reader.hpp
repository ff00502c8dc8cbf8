#pragma once
// RELLIS-3D sequence layout (also written by the synthetic generator):
//   os1_cloud_node_kitti_bin/NNNNNN.bin              scans, x y z intensity float32
//   os1_cloud_node_semantickitti_label_id/NNNNNN.label  per-point class ids (optional)
//   pylon_camera_node/frameNNNNNN-SEC_FRAC.jpg       camera images, stamped in the name
//   pylon_camera_node_label_id/<image stem>.png      2D label images (optional)
//   features/<image stem>.npy                        precomputed C x H x W feature maps (optional)
//   poses.txt (optional), times.txt (optional), camera_info.txt, transforms.yaml
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string_view>

#include "slamvdb/io/dataset.hpp"
#include "slamvdb/io/sequence_reader.hpp"

namespace slamvdb {

inline constexpr std::string_view kRellisScanDir = "os1_cloud_node_kitti_bin";
inline constexpr std::string_view kRellisScanLabelDir = "os1_cloud_node_semantickitti_label_id";
inline constexpr std::string_view kRellisImageDir = "pylon_camera_node";
inline constexpr std::string_view kRellisImageLabelDir = "pylon_camera_node_label_id";
// Not in RELLIS-3D: a SIMULATED sequence's view geometry images (synth/sequence_writer.hpp).
inline constexpr std::string_view kRellisSimViewDir = "pylon_camera_node_sim_view";

// Largest transforms.yaml read: 1 MiB (it holds one transform).
inline constexpr std::uint64_t kMaxYamlBytes = std::uint64_t{1} << 20;

Sequence read_rellis_sequence(const std::filesystem::path& dir, const ReadOptions& options = {});

// T_lidar_camera (the camera pose in the LiDAR frame) from the os1_cloud_node-pylon_camera_node
// entry of transforms.yaml: q (w x y z) and t (x y z). Project LiDAR points with its inverse.
// Every value must be a finite number and q a unit quaternion; errors name file:line.
Pose read_rellis_transforms(const std::filesystem::path& file);

// "fx fy cx cy" on the first line and optionally "k1 k2 p1 p2 k3" on the second; the intrinsics
// refer to images of `image_size`.
CameraModel read_rellis_camera_info(const std::filesystem::path& file, cv::Size image_size);

struct RellisImageName {
  int64_t frame = 0;
  double stamp = 0.0;
};
// "frame000104-1581624663_149" -> frame 104, stamp 1581624663.149 (the digits after '_' are the
// decimal fraction); nullopt if the stem has another form.
std::optional<RellisImageName> parse_rellis_image_name(std::string_view stem);

}  // namespace slamvdb
