#pragma once
// KITTI odometry sequence layout:
//   velodyne/NNNNNN.bin, image_2/NNNNNN.png, calib.txt (P0..P3, Tr), times.txt (one stamp per frame,
//   shared by scan and image), poses.txt (optional, camera-0 poses), labels/NNNNNN.label (optional,
//   SemanticKITTI), features/NNNNNN.npy (optional, precomputed C x H x W feature maps).
#include <filesystem>
#include <string_view>

#include "slamvdb/io/dataset.hpp"
#include "slamvdb/io/sequence_reader.hpp"

namespace slamvdb {

inline constexpr std::string_view kKittiScanDir = "velodyne";
inline constexpr std::string_view kKittiImageDir = "image_2";
inline constexpr std::string_view kKittiScanLabelDir = "labels";

struct KittiCalib {
  Eigen::Matrix<double, 3, 4> P2;  // rectified projection of camera 2 (the left colour camera)
  Pose T_cam0_velo;                // "Tr": LiDAR to camera 0
};
KittiCalib read_kitti_calib(const std::filesystem::path& file);

// Camera 2 intrinsics from P2 at the given image size (rectified: no distortion).
CameraModel kitti_camera(const KittiCalib& calib, int width, int height);
// Camera 2 pose in the LiDAR frame. P2 = K [I | t] with t the offset of camera 2 from camera 0,
// so t = K^-1 P2(:, 3) (for KITTI's P2, t_x = P2(0,3) / fx as its devkit defines).
Pose kitti_T_lidar_camera(const KittiCalib& calib);

// poses.txt holds T_world_cam0; the map wants T_world_lidar = T_world_cam0 * Tr.
Sequence read_kitti_sequence(const std::filesystem::path& dir, const ReadOptions& options = {});

}  // namespace slamvdb
