#pragma once
// Reading a recorded sequence whatever its layout (RELLIS-3D or KITTI odometry), plus the small
// text formats the layouts share (poses.txt, times.txt).
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

// Optional per-image precomputed feature maps: features/<image stem>.npy, in every layout.
inline constexpr std::string_view kFeatureDir = "features";

struct ReadOptions {
  // Plumb_bob coefficients (k1 k2 p1 p2 k3) replacing those of the sequence's calibration files,
  // e.g. RELLIS-3D's published distortion, which its camera_info.txt usually does not carry.
  std::optional<std::array<double, 5>> distortion;
};

// Detects the layout of `dir` (os1_cloud_node_kitti_bin/ -> RELLIS-3D, velodyne/ -> KITTI
// odometry) and reads it; throws Error listing what it looked for if neither is there.
Sequence read_sequence(const std::filesystem::path& dir, const ReadOptions& options = {});

// The numbers of every non-blank line of a whitespace-separated text file. Errors name file:line.
std::vector<std::vector<double>> read_number_rows(const std::filesystem::path& file);
// The numbers in `text`; `where` (e.g. "calib.txt:3") names the place in error messages.
std::vector<double> parse_numbers(std::string_view text, std::string_view where);

// A rigid transform from [R | t]; R is snapped to the nearest rotation (text files carry 6-10
// digits, and Pose's inverse assumes an exact rotation). Throws Error naming `where` if R is not
// within 1e-3 of a rotation.
Pose rigid_from_3x4(const Eigen::Matrix<double, 3, 4>& matrix, std::string_view where);
// One row-major 3x4 matrix [R | t] per line, as in KITTI's poses.txt.
std::vector<Pose> read_kitti_poses(const std::filesystem::path& file);
// One time stamp in seconds per line; throws Error naming the file unless strictly increasing.
std::vector<double> read_stamps(const std::filesystem::path& file);
// Throws Error naming `source` at the first stamp that is not after its predecessor.
void check_increasing(const std::vector<double>& stamps, std::string_view source);

// Regular files in `dir` with extension `ext` (e.g. ".bin"), digit-only stems in numeric order,
// others by name. Throws Error naming `dir` if it is not a directory.
std::vector<std::filesystem::path> list_files(const std::filesystem::path& dir, std::string_view ext);
// Throws Error naming `path` and what it was expected to be if it does not exist.
void require_exists(const std::filesystem::path& path, std::string_view what);

// One ScanRecord per scan file (stamps[i] for scan_files[i]) with its label file from label_dir
// when there is one; notes how many scans have none when label_dir exists.
std::vector<ScanRecord> scan_records(const std::vector<std::filesystem::path>& scan_files,
                                     const std::vector<double>& stamps, const std::filesystem::path& label_dir,
                                     std::vector<std::string>& notes);

// Applies the options' distortion to the sequence's camera (with a note) and validates the camera.
void apply_camera_options(Sequence& sequence, const ReadOptions& options);

}  // namespace slamvdb
