#pragma once
// Where the mapper's poses (T_world_lidar, stamped) come from, behind one interface: the
// sequence's ground truth, or an external trajectory file (KITTI 3x4 rows paired with the scans in
// order, or TUM "stamp tx ty tz qx qy qz qw") such as `slamvdb odometry` writes.
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "slamvdb/io/dataset.hpp"
#include "slamvdb/io/trajectory_io.hpp"

namespace slamvdb {

class PoseSource {
 public:
  virtual ~PoseSource() = default;
  virtual std::string describe() const = 0;
  // The poses for the scans of `sequence`. Throws Error naming the source when it has none that fit.
  virtual Trajectory trajectory(const Sequence& sequence) const = 0;
};

class DatasetPoses final : public PoseSource {
 public:
  std::string describe() const override { return "the sequence's ground truth (poses.txt)"; }
  Trajectory trajectory(const Sequence& sequence) const override;
};

class PoseFile final : public PoseSource {
 public:
  // format: nullopt detects it from the first row (12 numbers: KITTI, 8: TUM).
  explicit PoseFile(std::filesystem::path file, std::optional<PoseFormat> format = std::nullopt)
      : file_(std::move(file)), format_(format) {}
  std::string describe() const override;
  // KITTI rows carry no stamps: row i is the pose of scan i (a file with fewer rows leaves the
  // last scans without a pose, counted as such; more rows than scans is an Error).
  Trajectory trajectory(const Sequence& sequence) const override;

 private:
  std::filesystem::path file_;
  std::optional<PoseFormat> format_;
};

}  // namespace slamvdb
