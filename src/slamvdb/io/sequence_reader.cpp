#include "slamvdb/io/sequence_reader.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <fmt/std.h>

#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <tuple>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/kitti_reader.hpp"
#include "slamvdb/io/rellis_reader.hpp"

namespace slamvdb {

Sequence read_sequence(const std::filesystem::path& dir, const ReadOptions& options) {
  require_exists(dir, "sequence directory");
  if (std::filesystem::is_directory(dir / kRellisScanDir)) return read_rellis_sequence(dir, options);
  if (std::filesystem::is_directory(dir / kKittiScanDir)) return read_kitti_sequence(dir, options);
  throw Error(
      fmt::format("{} is neither a RELLIS-3D sequence (no {}/ folder) nor a KITTI odometry sequence "
                  "(no {}/ folder)",
                  dir, kRellisScanDir, kKittiScanDir));
}

std::vector<double> parse_numbers(std::string_view text, std::string_view where) {
  std::vector<double> numbers;
  const char* p = text.data();
  const char* end = text.data() + text.size();
  while (true) {
    while (p != end && std::isspace(static_cast<unsigned char>(*p))) ++p;
    if (p == end) break;
    double v = 0.0;
    const auto [next, ec] = std::from_chars(p, end, v);
    if (ec != std::errc() || (next != end && !std::isspace(static_cast<unsigned char>(*next))) || !std::isfinite(v))
      throw Error(fmt::format("{}: '{}' is not a number", where,
                              std::string_view(p, std::find_if(p, end, [](char c) {
                                                    return std::isspace(static_cast<unsigned char>(c));
                                                  }) - p)));
    numbers.push_back(v);
    p = next;
  }
  return numbers;
}

std::vector<std::vector<double>> read_number_rows(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw Error(fmt::format("cannot open {}", file));
  std::vector<std::vector<double>> rows;
  std::string line;
  for (int line_no = 1; std::getline(in, line); ++line_no) {
    auto numbers = parse_numbers(line, fmt::format("{}:{}", file.string(), line_no));
    if (!numbers.empty()) rows.push_back(std::move(numbers));
  }
  return rows;
}

Pose rigid_from_3x4(const Eigen::Matrix<double, 3, 4>& matrix, std::string_view where) {
  const Eigen::Matrix3d R = matrix.leftCols<3>();
  const double orthogonality = (R * R.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (!(orthogonality < 1e-3) || R.determinant() < 0)
    throw Error(
        fmt::format("{} is not a rigid transform: its 3x3 part is no rotation (|R R^T - I| = {:.2g}, det {:.3g})",
                    where, orthogonality, R.determinant()));
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Pose T = Pose::Identity();
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  T.translation() = matrix.col(3);
  return T;
}

std::vector<Pose> read_kitti_poses(const std::filesystem::path& file) {
  const auto rows = read_number_rows(file);
  std::vector<Pose> poses;
  poses.reserve(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].size() != 12)
      throw Error(
          fmt::format("{}: pose {} has {} numbers, expected 12 (a row-major 3x4 matrix)", file, i, rows[i].size()));
    poses.push_back(rigid_from_3x4(Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>>(rows[i].data()),
                                   fmt::format("{}: pose {}", file.string(), i)));
  }
  return poses;
}

std::vector<double> read_stamps(const std::filesystem::path& file) {
  const auto rows = read_number_rows(file);
  std::vector<double> stamps;
  stamps.reserve(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].size() != 1)
      throw Error(
          fmt::format("{}: entry {} has {} numbers, expected one time stamp per line", file, i, rows[i].size()));
    stamps.push_back(rows[i][0]);
  }
  check_increasing(stamps, file.string());
  return stamps;
}

void check_increasing(const std::vector<double>& stamps, std::string_view source) {
  for (std::size_t i = 1; i < stamps.size(); ++i)
    if (!(stamps[i] > stamps[i - 1]))
      throw Error(
          fmt::format("{}: time stamps must be strictly increasing, but stamp {} ({:.6f}) is not after "
                      "stamp {} ({:.6f})",
                      source, i, stamps[i], i - 1, stamps[i - 1]));
}

std::vector<std::filesystem::path> list_files(const std::filesystem::path& dir, std::string_view ext) {
  if (!std::filesystem::is_directory(dir)) throw Error(fmt::format("{} is not a directory", dir));
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir))
    if (entry.is_regular_file() && entry.path().extension() == ext) files.push_back(entry.path());
  // Digit-only stems first, by value (leading zeros stripped, then shorter is smaller); then by name.
  const auto key = [](const std::filesystem::path& p) {
    const std::string stem = p.stem().string();
    const bool numeric =
        !stem.empty() && std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; });
    const std::string digits = numeric ? stem.substr(std::min(stem.find_first_not_of('0'), stem.size())) : "";
    return std::make_tuple(!numeric, digits.size(), digits, p.filename().string());
  };
  std::sort(files.begin(), files.end(), [&](const auto& a, const auto& b) { return key(a) < key(b); });
  return files;
}

void require_exists(const std::filesystem::path& path, std::string_view what) {
  if (!std::filesystem::exists(path)) throw Error(fmt::format("{} {} does not exist", what, path));
}

void apply_camera_options(Sequence& sequence, const ReadOptions& options) {
  if (options.distortion) {
    sequence.camera.distortion = *options.distortion;
    sequence.notes.push_back(
        fmt::format("camera distortion (k1 k2 p1 p2 k3) = {} given by the user replaces the "
                    "calibration files'",
                    fmt::join(*options.distortion, " ")));
  } else if (!sequence.camera.has_distortion()) {
    sequence.notes.push_back("camera has no distortion coefficients: pinhole projection");
  }
  sequence.camera.validate();
}

std::vector<ScanRecord> scan_records(const std::vector<std::filesystem::path>& scan_files, const std::vector<double>& stamps,
                                     const std::filesystem::path& label_dir, std::vector<std::string>& notes) {
  std::vector<ScanRecord> scans;
  std::size_t without_labels = 0;
  for (std::size_t i = 0; i < scan_files.size(); ++i) {
    ScanRecord scan{stamps[i], scan_files[i], {}};
    if (const std::filesystem::path labels = label_dir / (scan_files[i].stem().string() + ".label"); std::filesystem::exists(labels))
      scan.labels = labels;
    without_labels += scan.labels.empty();
    scans.push_back(std::move(scan));
  }
  if (std::filesystem::is_directory(label_dir) && without_labels > 0)
    notes.push_back(
        fmt::format("{} of {} scans have no label file in {}", without_labels, scan_files.size(), label_dir));
  return scans;
}

}  // namespace slamvdb
