#include "slamvdb/io/kitti_reader.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <algorithm>
#include <charconv>
#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/io/image_io.hpp"

namespace slamvdb {

namespace {
namespace fs = std::filesystem;

// The frame index a KITTI file name stands for (000042.bin -> 42), checked against times.txt.
std::size_t frame_index(const fs::path& file, std::size_t frame_count, const fs::path& times_file) {
  const std::string stem = file.stem().string();
  std::size_t index = 0;
  const auto [end, ec] = std::from_chars(stem.data(), stem.data() + stem.size(), index);
  if (stem.empty() || ec != std::errc() || end != stem.data() + stem.size())
    throw Error(fmt::format("KITTI file {} is not named by its frame number (NNNNNN)", file));
  if (index >= frame_count)
    throw Error(
        fmt::format("KITTI file {} is frame {} but {} has only {} time stamps", file, index, times_file, frame_count));
  return index;
}
}  // namespace

KittiCalib read_kitti_calib(const fs::path& file) {
  const std::string text = read_regular_file(file, "KITTI calibration", kMaxNumberTextBytes);
  std::map<std::string, std::vector<double>> entries;
  std::size_t begin = 0;
  for (int line_no = 1; begin < text.size(); ++line_no) {
    const std::size_t newline = std::min(text.find('\n', begin), text.size());
    const std::string_view line = std::string_view(text).substr(begin, newline - begin);
    begin = newline + 1;
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    entries[std::string(line.substr(0, colon))] =
        parse_numbers(line.substr(colon + 1), fmt::format("{}:{}", file.string(), line_no));
  }
  const auto matrix = [&](std::initializer_list<const char*> keys) {
    for (const char* key : keys)
      if (const auto it = entries.find(key); it != entries.end()) {
        if (it->second.size() != 12)
          throw Error(
              fmt::format("{}: {} has {} numbers, expected 12 (a row-major 3x4 matrix)", file, key, it->second.size()));
        return Eigen::Matrix<double, 3, 4>(
            Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>>(it->second.data()));
      }
    throw Error(fmt::format("{} has no {} entry", file, *keys.begin()));
  };
  KittiCalib calib;
  calib.P2 = matrix({"P2"});
  // P2 = K [I | t] with K upper triangular, positive focal lengths and K(2,2) = 1 (a rectified
  // camera): anything else would give a singular K and a non-finite camera pose.
  const Eigen::Matrix3d K = calib.P2.leftCols<3>();
  if (!(K(0, 0) > 0 && K(1, 1) > 0 && K(2, 2) > 0) || K(1, 0) != 0 || K(2, 0) != 0 || K(2, 1) != 0)
    throw Error(fmt::format("{}: P2 is not a rectified camera projection K [I | t] (K upper triangular with positive "
                            "fx, fy and K(2,2))",
                            file));
  calib.T_cam0_velo = rigid_from_3x4(matrix({"Tr", "Tr_velo_to_cam"}), fmt::format("{}: Tr", file.string()));
  return calib;
}

CameraModel kitti_camera(const KittiCalib& calib, int width, int height) {
  CameraModel camera;
  camera.width = width;
  camera.height = height;
  camera.fx = calib.P2(0, 0);
  camera.fy = calib.P2(1, 1);
  camera.cx = calib.P2(0, 2);
  camera.cy = calib.P2(1, 2);
  return camera;
}

Pose kitti_T_lidar_camera(const KittiCalib& calib) {
  const Eigen::Matrix3d K = calib.P2.leftCols<3>();
  Pose T_cam2_cam0 = Pose::Identity();
  T_cam2_cam0.translation() = K.inverse() * calib.P2.col(3);
  return (T_cam2_cam0 * calib.T_cam0_velo).inverse();
}

Sequence read_kitti_sequence(const fs::path& dir, const ReadOptions& options) {
  Sequence seq;
  seq.root = dir;
  seq.layout = "kitti";
  const fs::path scan_dir = dir / kKittiScanDir, image_dir = dir / kKittiImageDir, label_dir = dir / kKittiScanLabelDir,
                 feature_dir = dir / kFeatureDir, times_file = dir / "times.txt";
  require_exists(scan_dir, "KITTI scan folder");
  require_exists(image_dir, "KITTI camera folder");
  require_exists(times_file, "KITTI time stamps");
  const auto stamps = read_stamps(times_file);
  const auto scan_files = list_files(scan_dir, ".bin");
  if (scan_files.empty()) throw Error(fmt::format("KITTI scan folder {} has no .bin files", scan_dir));
  if (scan_files.size() != stamps.size())
    throw Error(fmt::format("{} has {} time stamps but {} has {} scans", times_file, stamps.size(), scan_dir,
                            scan_files.size()));

  const KittiCalib calib = read_kitti_calib(dir / "calib.txt");
  const auto image_files = list_files(image_dir, ".png");
  if (image_files.empty()) throw Error(fmt::format("KITTI camera folder {} has no .png images", image_dir));
  // The size most images have: one damaged image must not change the camera model.
  const cv::Size image_size = common_image_size(image_files, options.max_image_pixels,
                                                fmt::format("camera images in {}", image_dir), seq.notes);
  seq.camera = kitti_camera(calib, image_size.width, image_size.height);
  apply_camera_options(seq, options);
  seq.T_lidar_camera = kitti_T_lidar_camera(calib);
  if (!seq.T_lidar_camera.matrix().allFinite())
    throw Error(fmt::format("{}: P2 and Tr give a non-finite camera pose (extreme values)", dir / "calib.txt"));

  std::size_t without_features = 0;
  for (const auto& file : image_files) {
    ImageRecord image{stamps[frame_index(file, stamps.size(), times_file)], file, {}, {}, {}};
    image.width = image_size.width;
    image.height = image_size.height;
    std::error_code ec;  // an inaccessible feature file is reported when it is read
    if (const fs::path features = feature_dir / (file.stem().string() + ".npy"); fs::exists(features, ec) || ec)
      image.features = features;
    without_features += image.features.empty();
    seq.images.push_back(std::move(image));
  }
  if (is_directory_or_throw(feature_dir) && without_features > 0)
    seq.notes.push_back(
        fmt::format("{} of {} images have no feature map in {}", without_features, image_files.size(), feature_dir));

  for (std::size_t i = 0; i < scan_files.size(); ++i)
    if (frame_index(scan_files[i], stamps.size(), times_file) != i)
      throw Error(fmt::format("KITTI scan {} is out of sequence: expected frame {}", scan_files[i], i));
  seq.scans = scan_records(scan_files, stamps, label_dir, seq.notes);

  if (const fs::path poses_file = dir / "poses.txt"; exists_or_throw(poses_file)) {
    const auto cam0_poses = read_kitti_poses(poses_file);
    if (cam0_poses.size() != scan_files.size())
      throw Error(fmt::format("{} has {} poses but {} has {} scans (one pose per scan expected)", poses_file,
                              cam0_poses.size(), scan_dir, scan_files.size()));
    std::vector<Pose> lidar_poses;
    for (const Pose& T_world_cam0 : cam0_poses) lidar_poses.push_back(T_world_cam0 * calib.T_cam0_velo);
    seq.poses = Trajectory(stamps, std::move(lidar_poses));
    seq.notes.push_back(
        "KITTI poses.txt gives camera-0 poses: converted to T_world_lidar = T_world_cam0 * Tr "
        "(the world frame stays the first camera-0 frame)");
  } else {
    seq.notes.push_back(fmt::format("no {}: the sequence has no ground-truth poses", poses_file));
  }
  return seq;
}

}  // namespace slamvdb
