#include "slamvdb/fusion/trajectory.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

Trajectory::Trajectory(std::vector<double> stamps, std::vector<Pose> poses)
    : stamps_(std::move(stamps)), poses_(std::move(poses)) {
  if (stamps_.size() != poses_.size())
    throw Error(fmt::format("trajectory has {} stamps but {} poses", stamps_.size(), poses_.size()));
  for (std::size_t i = 0; i < stamps_.size(); ++i) {
    if (!std::isfinite(stamps_[i])) throw Error(fmt::format("trajectory stamp {} is not finite", i));
    if (i > 0 && !(stamps_[i] > stamps_[i - 1]))
      throw Error(fmt::format("trajectory stamps out of order: stamp {} ({:.6f}) is not after stamp {} ({:.6f})",
                              i, stamps_[i], i - 1, stamps_[i - 1]));
  }
}

void Trajectory::append(double stamp, const Pose& pose) {
  if (!std::isfinite(stamp)) throw Error("trajectory stamp is not finite");
  if (!stamps_.empty() && !(stamp > stamps_.back()))
    throw Error(fmt::format("trajectory stamp {:.6f} is not after the last one ({:.6f})", stamp, stamps_.back()));
  stamps_.push_back(stamp);
  poses_.push_back(pose);
}

std::optional<Pose> Trajectory::at(double t) const {
  if (stamps_.empty() || !(t >= stamps_.front()) || !(t <= stamps_.back())) return std::nullopt;
  const auto it = std::lower_bound(stamps_.begin(), stamps_.end(), t);
  const std::size_t i1 = static_cast<std::size_t>(it - stamps_.begin());
  if (stamps_[i1] == t) return poses_[i1];
  const std::size_t i0 = i1 - 1;  // i1 > 0 because t > front here
  const double s = (t - stamps_[i0]) / (stamps_[i1] - stamps_[i0]);
  return interpolate_se3(poses_[i0], poses_[i1], s);
}

}  // namespace slamvdb
