#pragma once
// What `slamvdb odometry` reads: a dataset folder (RELLIS-3D or KITTI layout, via read_sequence)
// or a plain folder of scan files (KITTI .bin or .pcd) in name order. A plain folder's stamps come
// from a times.txt beside the scans (one per scan) if there is one, else scan i is stamped
// i / rate_hz (noted).
#include <filesystem>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fusion/trajectory.hpp"

namespace slamvdb {

struct ScanFile {
  double stamp = 0.0;
  std::filesystem::path path;  // .bin or .pcd
};

struct ScanSource {
  std::string kind;  // "rellis3d", "kitti" or "folder"
  std::vector<ScanFile> scans;
  Trajectory ground_truth;  // the dataset's poses.txt, if any
  std::vector<std::string> notes;
};

// Throws Error naming `input` if it is missing, holds no scans, or mixes .bin and .pcd files.
ScanSource open_scan_source(const std::filesystem::path& input, double rate_hz);

struct ScanPoints {
  std::vector<Vec3f> points;  // as stored, NaN and (0,0,0) included
  std::vector<float> time;    // per-point time when the file has it (PCD field t/time/timestamp)
};
ScanPoints load_scan_points(const ScanFile& scan);

}  // namespace slamvdb
