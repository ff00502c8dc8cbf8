#include "slamvdb/io/sequence_reader.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <fmt/std.h>

#include <sys/stat.h>

#include <Eigen/SVD>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <tuple>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/kitti_reader.hpp"
#include "slamvdb/io/rellis_reader.hpp"

namespace slamvdb {

Sequence read_sequence(const std::filesystem::path& dir, const ReadOptions& options) {
  require_exists(dir, "sequence directory");
  std::error_code ec;
  if (std::filesystem::exists(dir / kIncompleteMarker, ec) || std::filesystem::is_symlink(dir / kIncompleteMarker, ec))
    throw Error(fmt::format("sequence {} is incomplete: it holds {}, left by a writer (slamvdb synth) that failed or "
                            "was killed; write it again (synth --force)",
                            dir, kIncompleteMarker));
  if (is_directory_or_throw(dir / kRellisScanDir)) return read_rellis_sequence(dir, options);
  if (is_directory_or_throw(dir / kKittiScanDir)) return read_kitti_sequence(dir, options);
  throw Error(
      fmt::format("{} is neither a RELLIS-3D sequence (no {}/ folder) nor a KITTI odometry sequence "
                  "(no {}/ folder)",
                  dir, kRellisScanDir, kKittiScanDir));
}

std::vector<double> parse_numbers(std::string_view text, std::string_view where, std::size_t max_count) {
  std::vector<double> numbers;
  const char* p = text.data();
  const char* end = text.data() + text.size();
  const auto is_space = [](char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; };
  while (true) {
    while (p != end && is_space(*p)) ++p;
    if (p == end) break;
    double v = 0.0;
    const auto [next, ec] = std::from_chars(p, end, v);
    if (ec != std::errc() || (next != end && !is_space(*next)) || !std::isfinite(v)) {
      const std::string_view token(p, static_cast<std::size_t>(std::find_if(p, end, is_space) - p));
      throw Error(fmt::format("{}: '{}' is not a {}number", where, escape_control(token, 40),
                              ec == std::errc() && !std::isfinite(v) ? "finite " : ""));
    }
    if (numbers.size() == max_count)
      throw Error(fmt::format("{}: more than {} numbers on one line", where, max_count));
    numbers.push_back(v);
    p = next;
  }
  return numbers;
}

void for_each_number_row(const std::filesystem::path& file, std::string_view what,
                         const std::function<void(const NumberRow& row)>& row) {
  const std::string text = read_regular_file(file, what, kMaxNumberTextBytes);
  NumberRow current;
  std::size_t begin = 0;
  for (int line_no = 1; begin < text.size(); ++line_no) {
    const std::size_t newline = std::min(text.find('\n', begin), text.size());
    current.where = fmt::format("{}:{}", file.string(), line_no);
    current.numbers = parse_numbers(std::string_view(text).substr(begin, newline - begin), current.where);
    if (!current.numbers.empty()) row(current);
    begin = newline + 1;
  }
}

std::vector<NumberRow> read_number_rows(const std::filesystem::path& file, std::string_view what) {
  std::vector<NumberRow> rows;
  for_each_number_row(file, what, [&](const NumberRow& row) { rows.push_back(row); });
  return rows;
}

void check_pose_translation(const Vec3d& t, std::string_view where) {
  if (!(t.norm() <= kMaxPoseTranslation))
    throw Error(fmt::format("{}: the translation ({:.6g}, {:.6g}, {:.6g}) is {:.3g} m from the origin, beyond the "
                            "{:.0f} km a pose may be",
                            where, t.x(), t.y(), t.z(), t.norm(), kMaxPoseTranslation / 1e3));
}

Pose rigid_from_3x4(const Eigen::Matrix<double, 3, 4>& matrix, std::string_view where) {
  const Eigen::Matrix3d R = matrix.leftCols<3>();
  const double orthogonality = (R * R.transpose() - Eigen::Matrix3d::Identity()).norm();
  if (!(orthogonality < 1e-3) || R.determinant() < 0)
    throw Error(
        fmt::format("{} is not a rigid transform: its 3x3 part is no rotation (|R R^T - I| = {:.2g}, det {:.3g})",
                    where, orthogonality, R.determinant()));
  check_pose_translation(matrix.col(3), where);
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Pose T = Pose::Identity();
  T.linear() = svd.matrixU() * svd.matrixV().transpose();
  T.translation() = matrix.col(3);
  return T;
}

std::vector<Pose> read_kitti_poses(const std::filesystem::path& file) {
  std::vector<Pose> poses;
  for_each_number_row(file, "pose file", [&](const NumberRow& row) {
    if (row.numbers.size() != 12)
      throw Error(fmt::format("{}: pose {} has {} numbers, expected 12 (a row-major 3x4 matrix)", row.where,
                              poses.size(), row.numbers.size()));
    poses.push_back(
        rigid_from_3x4(Eigen::Map<const Eigen::Matrix<double, 3, 4, Eigen::RowMajor>>(row.numbers.data()),
                       fmt::format("{} (pose {})", row.where, poses.size())));
  });
  return poses;
}

std::vector<double> read_stamps(const std::filesystem::path& file) {
  std::vector<double> stamps;
  for_each_number_row(file, "time stamp file", [&](const NumberRow& row) {
    if (row.numbers.size() != 1)
      throw Error(fmt::format("{}: entry {} has {} numbers, expected one time stamp per line", row.where,
                              stamps.size(), row.numbers.size()));
    stamps.push_back(row.numbers[0]);
  });
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
  if (!is_directory_or_throw(dir)) throw Error(fmt::format("{} is not a directory", dir));
  std::vector<std::filesystem::path> files;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().extension() != ext) continue;
    std::error_code type_error;
    const auto status = it->status(type_error);  // follows symlinks
    if (type_error && type_error != std::errc::no_such_file_or_directory)
      throw Error(fmt::format("cannot read {}: {}", it->path(), type_error.message()));
    if (status.type() == std::filesystem::file_type::regular) {
      files.push_back(it->path());
    } else {
      struct stat st {};
      const bool dangling = ::stat(it->path().c_str(), &st) != 0;
      throw Error(fmt::format("{} is {}, not a regular {} file", it->path(),
                              dangling ? std::string_view("a dangling symbolic link") : describe_file_type(st.st_mode),
                              ext));
    }
  }
  if (ec) throw Error(fmt::format("cannot list the directory {}: {}", dir, ec.message()));
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
  std::error_code ec;
  const bool exists = std::filesystem::exists(path, ec);
  if (ec) throw Error(fmt::format("cannot access {} {}: {}", what, path, ec.message()));
  if (!exists) throw Error(fmt::format("{} {} does not exist", what, path));
}

bool exists_or_throw(const std::filesystem::path& path) {
  std::error_code ec;
  const auto status = std::filesystem::symlink_status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory)
    throw Error(fmt::format("cannot access {}: {}", path, ec.message()));
  return std::filesystem::exists(status);
}

bool is_directory_or_throw(const std::filesystem::path& path) {
  std::error_code ec;
  const bool directory = std::filesystem::is_directory(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory)
    throw Error(fmt::format("cannot access {}: {}", path, ec.message()));
  return directory;
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
    std::error_code ec;  // an inaccessible label file is reported when the scan is read
    if (const std::filesystem::path labels = label_dir / (scan_files[i].stem().string() + ".label");
        std::filesystem::exists(labels, ec) || ec)
      scan.labels = labels;
    without_labels += scan.labels.empty();
    scans.push_back(std::move(scan));
  }
  if (is_directory_or_throw(label_dir) && without_labels > 0)
    notes.push_back(
        fmt::format("{} of {} scans have no label file in {}", without_labels, scan_files.size(), label_dir));
  return scans;
}

}  // namespace slamvdb
