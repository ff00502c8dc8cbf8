#include "slamvdb/io/rellis_reader.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/image_io.hpp"

namespace slamvdb {

namespace {
namespace fs = std::filesystem;

std::optional<int64_t> parse_integer(std::string_view digits) {
  if (digits.empty() || !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return std::nullopt;
  int64_t v = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (ec != std::errc() || end != digits.data() + digits.size()) return std::nullopt;
  return v;
}

struct StampedImage {
  RellisImageName name;
  ImageRecord record;
};

// Camera images and label images share stems; either folder alone is enough (a simulated
// sequence may have label images only).
std::vector<StampedImage> collect_images(const fs::path& dir, std::vector<std::string>& notes) {
  const fs::path rgb_dir = dir / kRellisImageDir, label_dir = dir / kRellisImageLabelDir,
                 feature_dir = dir / kFeatureDir;
  const bool has_rgb_dir = is_directory_or_throw(rgb_dir), has_label_dir = is_directory_or_throw(label_dir);
  if (!has_rgb_dir && !has_label_dir)
    throw Error(fmt::format("RELLIS-3D sequence {} has no camera images: neither {} nor {} is a directory", dir,
                            rgb_dir, label_dir));
  std::map<std::string, ImageRecord> by_stem;
  if (has_rgb_dir)
    for (const char* ext : {".jpg", ".jpeg", ".png"})
      for (const auto& file : list_files(rgb_dir, ext)) by_stem[file.stem().string()].rgb = file;
  if (has_label_dir)
    for (const auto& file : list_files(label_dir, ".png")) by_stem[file.stem().string()].labels = file;

  std::vector<StampedImage> images;
  std::size_t without_rgb = 0, without_labels = 0, without_features = 0;
  for (auto& [stem, record] : by_stem) {
    const auto name = parse_rellis_image_name(stem);
    if (!name)
      throw Error(
          fmt::format("image {} is not named frameNNNNNN-SECONDS_FRACTION (RELLIS-3D), so it has no "
                      "frame number and time stamp",
                      record.rgb.empty() ? record.labels : record.rgb));
    record.stamp = name->stamp;
    const fs::path features = feature_dir / (stem + ".npy");
    std::error_code ec;  // an inaccessible feature file is reported when it is read
    if (fs::exists(features, ec) || ec) record.features = features;
    const fs::path view = dir / kRellisSimViewDir / (stem + ".png");
    if (fs::exists(view, ec) || ec) record.view = view;
    without_rgb += record.rgb.empty();
    without_labels += record.labels.empty();
    without_features += record.features.empty();
    images.push_back({*name, std::move(record)});
  }
  if (images.empty())
    throw Error(fmt::format("RELLIS-3D sequence {} has no images in {} or {}", dir, rgb_dir, label_dir));
  std::sort(images.begin(), images.end(), [](const auto& a, const auto& b) { return a.name.stamp < b.name.stamp; });
  std::vector<double> stamps;
  for (const auto& image : images) stamps.push_back(image.record.stamp);
  check_increasing(stamps, fmt::format("camera images in {} (stamps from the file names)", dir));

  if (has_rgb_dir && without_rgb > 0)
    notes.push_back(fmt::format("{} of {} images have a label image but no camera image", without_rgb, images.size()));
  if (has_label_dir && without_labels > 0)
    notes.push_back(fmt::format("{} of {} images have no label image in {}", without_labels, images.size(), label_dir));
  if (is_directory_or_throw(feature_dir) && without_features > 0)
    notes.push_back(
        fmt::format("{} of {} images have no feature map in {}", without_features, images.size(), feature_dir));
  return images;
}

// Without times.txt, scan stamps come from the camera: RELLIS-3D numbers its scans and camera
// frames alike, and scan NNNNNN was captured together with frameNNNNNN (on the published frame
// 000104 they are 21 ms apart). A scan without its frame is placed linearly between the nearest
// paired scans, or beyond the first/last one at the mean period of all pairs.
std::vector<double> stamps_from_frames(const std::vector<fs::path>& scan_files, const std::vector<StampedImage>& images,
                                       const fs::path& dir, std::vector<std::string>& notes) {
  std::map<int64_t, const StampedImage*> by_frame;
  for (const auto& image : images) {
    const auto [it, inserted] = by_frame.emplace(image.name.frame, &image);
    if (!inserted)
      throw Error(fmt::format("two images have frame number {}: {} and {}", image.name.frame,
                              it->second->record.rgb.empty() ? it->second->record.labels : it->second->record.rgb,
                              image.record.rgb.empty() ? image.record.labels : image.record.rgb));
  }
  std::vector<int64_t> numbers;
  std::vector<std::pair<int64_t, double>> anchors;  // (scan number, stamp of its frame)
  for (const auto& file : scan_files) {
    const auto number = parse_integer(file.stem().string());
    if (!number)
      throw Error(
          fmt::format("scan {} has no frame number in its name to pair it with a camera frame; provide {} "
                      "with one time stamp per scan",
                      file, dir / "times.txt"));
    numbers.push_back(*number);
    if (const auto it = by_frame.find(*number); it != by_frame.end())
      anchors.emplace_back(*number, it->second->name.stamp);
  }
  if (anchors.empty() || (anchors.size() == 1 && numbers.size() > 1))
    throw Error(
        fmt::format("cannot time the scans of {}: {} of {} scans have a camera frame with the same number, "
                    "too few to infer the scan rate; provide {} with one time stamp per scan",
                    dir, anchors.size(), numbers.size(), dir / "times.txt"));
  const double period = anchors.size() > 1 ? (anchors.back().second - anchors.front().second) /
                                                 static_cast<double>(anchors.back().first - anchors.front().first)
                                           : 0.0;
  std::vector<double> stamps;
  for (const int64_t n : numbers) {
    const auto hi = std::lower_bound(anchors.begin(), anchors.end(), std::pair<int64_t, double>(n, -INFINITY));
    if (hi != anchors.end() && hi->first == n) {
      stamps.push_back(hi->second);
    } else if (hi == anchors.begin()) {
      stamps.push_back(hi->second - static_cast<double>(hi->first - n) * period);
    } else if (hi == anchors.end()) {
      stamps.push_back(anchors.back().second + static_cast<double>(n - anchors.back().first) * period);
    } else {
      const auto lo = hi - 1;
      const double s = static_cast<double>(n - lo->first) / static_cast<double>(hi->first - lo->first);
      stamps.push_back(lo->second + s * (hi->second - lo->second));
    }
  }
  check_increasing(stamps, fmt::format("scan stamps taken from the camera frame names in {}", dir / kRellisImageDir));
  notes.push_back(fmt::format(
      "no times.txt: scan NNNNNN takes the stamp of camera frameNNNNNN (RELLIS-3D pairing; 21 ms apart on the "
      "published frame 000104); {} of {} scans had no frame and were interpolated or extrapolated at the mean frame "
      "period {:.4f} s",
      numbers.size() - anchors.size(), numbers.size(), period));
  return stamps;
}
}  // namespace

std::optional<RellisImageName> parse_rellis_image_name(std::string_view stem) {
  constexpr std::string_view kPrefix = "frame";
  if (!stem.starts_with(kPrefix)) return std::nullopt;
  stem.remove_prefix(kPrefix.size());
  const auto dash = stem.find('-'), underscore = stem.rfind('_');
  if (dash == std::string_view::npos || underscore == std::string_view::npos || underscore < dash) return std::nullopt;
  const auto frame = parse_integer(stem.substr(0, dash));
  const auto seconds = parse_integer(stem.substr(dash + 1, underscore - dash - 1));
  const std::string_view fraction = stem.substr(underscore + 1);
  const auto fraction_value = parse_integer(fraction);
  if (!frame || !seconds || !fraction_value || fraction.size() > 18) return std::nullopt;
  return RellisImageName{
      *frame, static_cast<double>(*seconds) +
                  static_cast<double>(*fraction_value) / std::pow(10.0, static_cast<double>(fraction.size()))};
}

Pose read_rellis_transforms(const fs::path& file) {
  constexpr const char* kKey = "os1_cloud_node-pylon_camera_node";
  const std::string text = read_regular_file(file, "camera-LiDAR extrinsics", kMaxYamlBytes);
  try {
    const YAML::Node root = YAML::Load(text);
    if (!root.IsMap()) throw Error(fmt::format("{} is not a YAML mapping with a '{}' entry", file, kKey));
    const YAML::Node entry = root[kKey];
    if (!entry || !entry.IsMap()) throw Error(fmt::format("{} has no '{}' entry", file, kKey));
    const YAML::Node q = entry["q"], t = entry["t"];
    if (!q || !t || !q.IsMap() || !t.IsMap())
      throw Error(fmt::format("{}: '{}' needs 'q' (w x y z) and 't' (x y z)", file, kKey));
    // Every value finite: a NaN quaternion would give a NaN camera pose, and every voxel would then
    // silently miss the image.
    const auto number = [&](const YAML::Node& parent, const char* parent_key, const char* key) {
      const YAML::Node v = parent[key];
      if (!v) throw Error(fmt::format("{}: '{}.{}.{}' is missing", file, kKey, parent_key, key));
      if (!v.IsScalar())
        throw Error(fmt::format("{}:{}: '{}.{}' must be a number", file.string(), v.Mark().line + 1, parent_key, key));
      double value = 0.0;
      if (!YAML::convert<double>::decode(v, value) || !std::isfinite(value))
        throw Error(fmt::format("{}:{}: '{}.{}' is '{}', not a finite number", file.string(), v.Mark().line + 1, parent_key,
                                key, escape_control(v.Scalar(), 40)));
      return value;
    };
    Eigen::Quaterniond rotation(number(q, "q", "w"), number(q, "q", "x"), number(q, "q", "y"), number(q, "q", "z"));
    if (std::abs(rotation.norm() - 1.0) > 1e-3)
      throw Error(fmt::format("{}:{}: quaternion q has norm {:.6f}, expected a unit quaternion", file.string(),
                              q.Mark().line + 1, rotation.norm()));
    Pose T_lidar_camera = Pose::Identity();
    T_lidar_camera.linear() = rotation.normalized().toRotationMatrix();
    T_lidar_camera.translation() = Vec3d(number(t, "t", "x"), number(t, "t", "y"), number(t, "t", "z"));
    check_pose_translation(T_lidar_camera.translation(), fmt::format("{}:{}", file.string(), t.Mark().line + 1));
    return T_lidar_camera;
  } catch (const YAML::Exception& e) {
    throw Error(fmt::format("cannot read camera-LiDAR extrinsics {}: {}", file, e.what()));
  }
}

CameraModel read_rellis_camera_info(const fs::path& file, cv::Size image_size) {
  require_exists(file, "camera intrinsics");
  const auto rows = read_number_rows(file, "camera intrinsics");
  if (rows.empty() || rows[0].numbers.size() != 4 || rows.size() > 2 ||
      (rows.size() == 2 && rows[1].numbers.size() != 5))
    throw Error(
        fmt::format("{} must hold 'fx fy cx cy' on its first line and optionally 'k1 k2 p1 p2 k3' on the "
                    "second",
                    file));
  CameraModel camera;
  camera.width = image_size.width;
  camera.height = image_size.height;
  camera.fx = rows[0].numbers[0];
  camera.fy = rows[0].numbers[1];
  camera.cx = rows[0].numbers[2];
  camera.cy = rows[0].numbers[3];
  if (rows.size() == 2) std::copy(rows[1].numbers.begin(), rows[1].numbers.end(), camera.distortion.begin());
  return camera;
}

Sequence read_rellis_sequence(const fs::path& dir, const ReadOptions& options) {
  Sequence seq;
  seq.root = dir;
  seq.layout = "rellis3d";
  const fs::path scan_dir = dir / kRellisScanDir, label_dir = dir / kRellisScanLabelDir;
  require_exists(scan_dir, "RELLIS-3D scan folder");
  const auto scan_files = list_files(scan_dir, ".bin");
  if (scan_files.empty()) throw Error(fmt::format("RELLIS-3D scan folder {} has no .bin files", scan_dir));

  const auto images = collect_images(dir, seq.notes);
  // The camera's size is the one most images have (from their headers): one damaged image must
  // not change the camera model; images of another size are refused when loaded.
  std::vector<fs::path> rgb_files, label_files;
  for (const auto& image : images) {
    if (!image.record.rgb.empty()) rgb_files.push_back(image.record.rgb);
    if (!image.record.labels.empty()) label_files.push_back(image.record.labels);
  }
  const cv::Size image_size =
      rgb_files.empty()
          ? common_image_size(label_files, options.max_image_pixels,
                              fmt::format("label images in {}", dir / kRellisImageLabelDir), seq.notes)
          : common_image_size(rgb_files, options.max_image_pixels,
                              fmt::format("camera images in {}", dir / kRellisImageDir), seq.notes);
  for (const auto& image : images) {
    seq.images.push_back(image.record);
    seq.images.back().width = image_size.width;
    seq.images.back().height = image_size.height;
  }
  seq.camera = read_rellis_camera_info(dir / "camera_info.txt", image_size);
  apply_camera_options(seq, options);
  seq.T_lidar_camera = read_rellis_transforms(dir / "transforms.yaml");

  std::vector<double> stamps;
  if (const fs::path times = dir / "times.txt"; exists_or_throw(times)) {
    stamps = read_stamps(times);
    if (stamps.size() != scan_files.size())
      throw Error(
          fmt::format("{} has {} time stamps but {} has {} scans", times, stamps.size(), scan_dir, scan_files.size()));
  } else {
    stamps = stamps_from_frames(scan_files, images, dir, seq.notes);
  }

  seq.scans = scan_records(scan_files, stamps, label_dir, seq.notes);

  if (const fs::path poses_file = dir / "poses.txt"; exists_or_throw(poses_file)) {
    auto poses = read_kitti_poses(poses_file);
    if (poses.size() != scan_files.size())
      throw Error(fmt::format("{} has {} poses but {} has {} scans (one T_world_lidar per scan expected)", poses_file,
                              poses.size(), scan_dir, scan_files.size()));
    seq.poses = Trajectory(std::move(stamps), std::move(poses));
  } else {
    seq.notes.push_back(fmt::format("no {}: the sequence has no ground-truth poses", poses_file));
  }
  return seq;
}

}  // namespace slamvdb
