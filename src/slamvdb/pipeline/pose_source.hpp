#pragma once
// Where the mapper's poses (T_world_lidar, stamped) come from, behind one interface: the
// sequence's ground truth, an external trajectory file (KITTI 3x4 rows paired with the scans in
// order, or TUM "stamp tx ty tz qx qy qz qw") such as `slamvdb odometry` writes, or the project's
// own LiDAR odometry and loop closure run over the sequence's scans.
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "slamvdb/io/dataset.hpp"
#include "slamvdb/io/trajectory_io.hpp"
#include "slamvdb/pipeline/lidar_tracking.hpp"
#include "slamvdb/pipeline/scan_deskew.hpp"
#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb {

class PoseSource {
 public:
  virtual ~PoseSource() = default;
  virtual std::string describe() const = 0;
  // The poses for the scans of `input`. Throws Error naming the source when it has none that fit.
  virtual Trajectory trajectory(const SensorInput& input) const = 0;
  Trajectory trajectory(const Sequence& sequence) const { return trajectory(*sequence_input(sequence)); }
};

class DatasetPoses final : public PoseSource {
 public:
  std::string describe() const override { return "the input's ground truth (poses.txt, or a recording's pose topic or tf)"; }
  using PoseSource::trajectory;
  Trajectory trajectory(const SensorInput& input) const override;
};

class PoseFile final : public PoseSource {
 public:
  // format: nullopt detects it from the first row (12 numbers: KITTI, 8: TUM).
  explicit PoseFile(std::filesystem::path file, std::optional<PoseFormat> format = std::nullopt)
      : file_(std::move(file)), format_(format) {}
  std::string describe() const override;
  // KITTI rows carry no stamps: row i is the pose of scan i (a file with fewer rows leaves the
  // last scans without a pose, counted as such; more rows than scans is an Error).
  // A recording's scans are not listed before reading: KITTI files need a dataset folder.
  using PoseSource::trajectory;
  Trajectory trajectory(const SensorInput& input) const override;

 private:
  std::filesystem::path file_;
  std::optional<PoseFormat> format_;
};

// Where the project's odometry frame (the first scan's sensor frame) sits in the world: the
// sequence's ground-truth pose at that scan when it has one (the start is known, as on a robot,
// so maps compare with ground-truth ones), else the identity.
Pose odometry_start_pose(const Sequence& sequence, double first_scan_stamp);

// The project's own poses in a first pass over the scans (odometry, then loop-corrected when loop
// closure is on); `slamvdb slam` instead maps in the same pass and moves submaps as loops close.
// The odometry frame is placed by odometry_start_pose. An unreadable scan gets no pose (the mapper counts it when it reads it).
class OdometryPoses final : public PoseSource {
 public:
  explicit OdometryPoses(TrackingOptions options, TrackingProgress progress = {})
      : options_(std::move(options)), progress_(std::move(progress)) {}
  // After trajectory(): also how the tracking went.
  std::string describe() const override;
  using PoseSource::trajectory;
  Trajectory trajectory(const SensorInput& input) const override;
  const std::vector<std::string>& problems() const { return problems_; }  // one line per scan not registered
  // After trajectory(): the motion each deskewed scan was deskewed with, by stamp (the mapping
  // deskews the whole scan the same way: PipelineOptions::sweeps).
  const SweepMotions& sweeps() const { return sweeps_; }

 private:
  TrackingOptions options_;
  TrackingProgress progress_;
  mutable std::string summary_;
  mutable std::vector<std::string> problems_;
  mutable SweepMotions sweeps_;
};

}  // namespace slamvdb
