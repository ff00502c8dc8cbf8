#include "slamvdb/pipeline/pose_source.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

Trajectory DatasetPoses::trajectory(const Sequence& sequence) const {
  if (sequence.poses.empty())
    throw Error(fmt::format("sequence {} has no ground-truth poses (poses.txt); give a pose file with --poses",
                            sequence.root.string()));
  return sequence.poses;
}

std::string PoseFile::describe() const {
  const char* kind = !format_ ? "" : *format_ == PoseFormat::kKitti ? "KITTI " : "TUM ";
  return fmt::format("{}pose file {}", kind, file_.string());
}

Trajectory PoseFile::trajectory(const Sequence& sequence) const {
  StampedPoses poses = read_trajectory(file_, format_);
  if (poses.format == PoseFormat::kKitti) {
    if (poses.poses.size() > sequence.scans.size())
      throw Error(fmt::format("{} has {} poses but the sequence has only {} scans; a KITTI pose file pairs row i with "
                              "scan i", file_.string(), poses.poses.size(), sequence.scans.size()));
    for (std::size_t i = 0; i < poses.poses.size(); ++i) poses.stamps[i] = sequence.scans[i].stamp;
  }
  try {
    return Trajectory(std::move(poses.stamps), std::move(poses.poses));
  } catch (const Error& e) {
    throw Error(fmt::format("{}: {}", file_.string(), e.what()));
  }
}

}  // namespace slamvdb
