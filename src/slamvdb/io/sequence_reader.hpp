#pragma once
// Reading a recorded sequence whatever its layout (RELLIS-3D or KITTI odometry), plus the small
// text formats the layouts share (poses.txt, times.txt).
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
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
  // Largest camera / label image accepted (pixels), checked from the image headers before any
  // image is decoded.
  std::int64_t max_image_pixels = kDefaultMaxImagePixels;
};

// Detects the layout of `dir` (os1_cloud_node_kitti_bin/ -> RELLIS-3D, velodyne/ -> KITTI
// odometry) and reads it; throws Error listing what it looked for if neither is there, and if
// the sequence is incomplete (kIncompleteMarker). Every file the readers open must be a regular
// file; a FIFO, directory or device in its place is an Error naming it (nothing can block).
Sequence read_sequence(const std::filesystem::path& dir, const ReadOptions& options = {});

// A sequence holding this file is incomplete: writers of sequences (slamvdb synth) create it
// first and remove it last, so a writer that failed or was killed leaves it behind, and
// read_sequence refuses the sequence instead of mapping part of it.
inline constexpr std::string_view kIncompleteMarker = ".slamvdb-incomplete";

// Largest text file of numbers read (poses.txt, times.txt, calibration): 64 MiB, about 300 000
// poses or 3 million time stamps. Bigger files are refused before they are read.
inline constexpr std::uint64_t kMaxNumberTextBytes = std::uint64_t{64} << 20;
// Most numbers on one line of such a file (a 3x4 matrix has 12).
inline constexpr std::size_t kMaxNumbersPerLine = 64;

// One non-blank line of a whitespace-separated text file of numbers.
struct NumberRow {
  std::string where;            // "file:line", for messages
  std::vector<double> numbers;  // all finite
};
// Calls `row` for every non-blank line of `file` (a regular file; `what` names it in messages:
// "time stamp file", ...). Errors name file:line; a non-finite number is an error.
void for_each_number_row(const std::filesystem::path& file, std::string_view what,
                         const std::function<void(const NumberRow& row)>& row);
// All rows at once, for small files.
std::vector<NumberRow> read_number_rows(const std::filesystem::path& file, std::string_view what);
// The numbers in `text` (at most `max_count`); `where` (e.g. "calib.txt:3") names the place in
// error messages, which quote the offending token with control characters escaped.
std::vector<double> parse_numbers(std::string_view text, std::string_view where,
                                  std::size_t max_count = kMaxNumbersPerLine);

// Largest distance of a pose from the origin: 10 000 km (UTM northings reach 9 300 km). Farther
// poses are refused: no robot drives there, and it keeps every voxel a map can see inside the
// 32-bit key range even at the smallest voxel size the CLI allows (0.01 m: +-21 000 km).
inline constexpr double kMaxPoseTranslation = 1e7;

// A rigid transform from [R | t]; R is snapped to the nearest rotation (text files carry 6-10
// digits, and Pose's inverse assumes an exact rotation). Throws Error naming `where` if R is not
// within 1e-3 of a rotation or t is farther than kMaxPoseTranslation.
Pose rigid_from_3x4(const Eigen::Matrix<double, 3, 4>& matrix, std::string_view where);
// Throws Error naming `where` if `t` is farther than kMaxPoseTranslation from the origin.
void check_pose_translation(const Vec3d& t, std::string_view where);
// One row-major 3x4 matrix [R | t] per line, as in KITTI's poses.txt.
std::vector<Pose> read_kitti_poses(const std::filesystem::path& file);
// One time stamp in seconds per line; throws Error naming the file unless strictly increasing.
std::vector<double> read_stamps(const std::filesystem::path& file);
// Throws Error naming `source` at the first stamp that is not after its predecessor.
void check_increasing(const std::vector<double>& stamps, std::string_view source);

// Regular files in `dir` with extension `ext` (e.g. ".bin"), digit-only stems in numeric order,
// others by name. Throws Error naming `dir` if it is not a directory or cannot be listed, and
// naming the entry if one with that extension is not a regular file (a FIFO, a directory, ...).
std::vector<std::filesystem::path> list_files(const std::filesystem::path& dir, std::string_view ext);
// Throws Error naming `path` and what it was expected to be if it does not exist (or cannot be
// accessed).
void require_exists(const std::filesystem::path& path, std::string_view what);
// Whether something (of any file type) is at `path`; throws Error naming it if that cannot be
// told (e.g. permission denied on a parent). A FIFO or directory found here is refused by the
// reader that opens it, with a message naming it.
bool exists_or_throw(const std::filesystem::path& path);
// Whether `path` is a directory (after symlinks); false if it does not exist; throws Error naming
// it if it cannot be accessed (e.g. permission denied on a parent).
bool is_directory_or_throw(const std::filesystem::path& path);

// One ScanRecord per scan file (stamps[i] for scan_files[i]) with its label file from label_dir
// when there is one; notes how many scans have none when label_dir exists.
std::vector<ScanRecord> scan_records(const std::vector<std::filesystem::path>& scan_files,
                                     const std::vector<double>& stamps, const std::filesystem::path& label_dir,
                                     std::vector<std::string>& notes);

// Applies the options' distortion to the sequence's camera (with a note) and validates the camera.
void apply_camera_options(Sequence& sequence, const ReadOptions& options);

}  // namespace slamvdb
