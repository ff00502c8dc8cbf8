#pragma once
// A time-stamped pose sequence with SE(3) interpolation.
#include <optional>
#include <vector>

#include "slamvdb/core/se3.hpp"
#include "slamvdb/core/types.hpp"

namespace slamvdb {

class Trajectory {
 public:
  Trajectory() = default;
  // Throws Error if sizes differ or stamps are not strictly increasing (names the offending index).
  Trajectory(std::vector<double> stamps, std::vector<Pose> poses);

  // Extends the trajectory as poses arrive (the streaming mapper). Throws Error for a stamp that
  // is not finite or not after the last one; the trajectory is then unchanged.
  void append(double stamp, const Pose& pose);

  // Pose at time t, interpolated between the two nearest poses; nullopt outside [front, back].
  std::optional<Pose> at(double t) const;
  bool empty() const { return stamps_.empty(); }
  std::size_t size() const { return stamps_.size(); }
  double front_stamp() const { return stamps_.front(); }
  double back_stamp() const { return stamps_.back(); }
  const std::vector<double>& stamps() const { return stamps_; }
  const std::vector<Pose>& poses() const { return poses_; }

 private:
  std::vector<double> stamps_;
  std::vector<Pose> poses_;
};

}  // namespace slamvdb
