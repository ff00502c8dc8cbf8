#pragma once
// Trajectory files: KITTI (one row-major 3x4 [R | t] per line, no stamps) and TUM
// ("stamp tx ty tz qx qy qz qw" per line, '#' comments).
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

enum class PoseFormat { kKitti, kTum };

struct StampedPoses {
  std::vector<double> stamps;  // KITTI files have none: 0, 1, 2, ... (pairing by index)
  std::vector<Pose> poses;
  PoseFormat format = PoseFormat::kKitti;
};

// Reads `file` in `format`, or detects it from the first row (12 numbers: KITTI, 8: TUM).
// Throws Error naming the file and line on anything malformed.
StampedPoses read_trajectory(const std::filesystem::path& file, std::optional<PoseFormat> format = std::nullopt);
void write_trajectory(const std::filesystem::path& file, const std::vector<double>& stamps,
                      const std::vector<Pose>& poses, PoseFormat format);
std::optional<PoseFormat> parse_pose_format(const std::string& name);  // "kitti" / "tum"

}  // namespace slamvdb
