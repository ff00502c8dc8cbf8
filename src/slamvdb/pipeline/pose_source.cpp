#include "slamvdb/pipeline/pose_source.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

Trajectory DatasetPoses::trajectory(const SensorInput& input) const {
  const Sequence& sequence = input.sequence();
  if (sequence.poses.empty())
    throw Error(input.is_recording()
                    ? fmt::format("recording {} has no pose topic chosen (--pose-topic), so no poses; give one, a pose "
                                  "file with --poses, or --odometry",
                                  sequence.root.string())
                    : fmt::format("sequence {} has no ground-truth poses (poses.txt); give a pose file with --poses",
                                  sequence.root.string()));
  return sequence.poses;
}

std::string PoseFile::describe() const {
  const char* kind = !format_ ? "" : *format_ == PoseFormat::kKitti ? "KITTI " : "TUM ";
  return fmt::format("{}pose file {}", kind, file_.string());
}

Trajectory PoseFile::trajectory(const SensorInput& input) const {
  const Sequence& sequence = input.sequence();
  StampedPoses poses = read_trajectory(file_, format_);
  if (poses.format == PoseFormat::kKitti && input.is_recording())
    throw Error(fmt::format("{} is a KITTI pose file (no stamps, row i = scan i): with a recording give a TUM file "
                            "(stamp tx ty tz qx qy qz qw) or --pose-topic", file_.string()));
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

Pose odometry_start_pose(const Sequence& sequence, double first_scan_stamp) {
  if (sequence.poses.empty()) return Pose::Identity();
  return sequence.poses.at(first_scan_stamp).value_or(Pose::Identity());
}

std::string OdometryPoses::describe() const {
  return fmt::format("the project's LiDAR odometry{}{}", options_.loop_closure ? " with loop closure" : "",
                     summary_.empty() ? "" : " (" + summary_ + ")");
}

Trajectory OdometryPoses::trajectory(const SensorInput& input) const {
  const Sequence& sequence = input.sequence();
  LidarTracker tracker(options_);
  sweeps_.clear();
  std::size_t unreadable = 0, done = 0;
  const auto stream = input.open(false);
  SensorFrame frame;
  while (stream->next(frame)) {
    if (frame.kind != SensorFrame::Kind::kScan) continue;
    if (frame.error.empty()) {
      tracker.track(frame.stamp, frame.points, frame.point_times.empty() ? nullptr : &frame.point_times, frame.name);
      if (tracker.last_sweep()) sweeps_[frame.stamp] = *tracker.last_sweep();
    } else {
      ++unreadable;  // no pose for it; the mapper reports the file when it reads it
    }
    if (progress_) progress_(++done, input.scan_count(), tracker.result());
  }
  const TrackingResult& r = tracker.result();
  if (r.stamps.empty()) throw Error(fmt::format("{}: no scan could be read for odometry", sequence.root.string()));
  tracker.require_registered(sequence.root.string(), unreadable);
  const Pose T_world_odom = odometry_start_pose(sequence, r.stamps.front());
  std::vector<Pose> poses;
  for (std::size_t i = 0; i < r.stamps.size(); ++i) poses.push_back(T_world_odom * r.corrected(i));
  std::size_t failed = 0;
  for (const auto& [reason, n] : r.failures) failed += n;
  summary_ = fmt::format("{} scans registered, {} predicted only, {} unreadable, {:.1f} m{}", r.registered(), failed,
                         unreadable, r.distance,
                         r.loop_closer ? fmt::format(", {} loops", r.loop_closer->loops().size()) : "");
  problems_ = r.problems;
  return Trajectory(r.stamps, std::move(poses));
}

}  // namespace slamvdb
