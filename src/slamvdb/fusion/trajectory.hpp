#pragma once
// A time-stamped pose sequence with SE(3) interpolation.
#include <optional>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

// exp / log of SE(3) with the twist ordered (rho, phi): translation part first.
using Twist = Eigen::Matrix<double, 6, 1>;
Pose se3_exp(const Twist& xi);
Twist se3_log(const Pose& T);
// Geodesic interpolation: T0 * exp(s * log(T0^-1 * T1)), s in [0, 1].
Pose interpolate_se3(const Pose& T0, const Pose& T1, double s);

class Trajectory {
 public:
  Trajectory() = default;
  // Throws Error if sizes differ or stamps are not strictly increasing (names the offending index).
  Trajectory(std::vector<double> stamps, std::vector<Pose> poses);

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
