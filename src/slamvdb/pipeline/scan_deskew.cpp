#include "slamvdb/pipeline/scan_deskew.hpp"

#include "slamvdb/core/se3.hpp"

namespace slamvdb {

namespace {
// T_world_sensor at `t`, extrapolated beyond the trajectory's ends (at least two poses).
Pose trajectory_pose_at(const Trajectory& poses, double t) {
  if (const auto inside = poses.at(t)) return *inside;
  const std::vector<double>& s = poses.stamps();
  const std::vector<Pose>& T = poses.poses();
  const std::size_t i = t < s.front() ? 0 : s.size() - 2;  // the first or the last segment
  return interpolate_se3(T[i], T[i + 1], (t - s[i]) / (s[i + 1] - s[i]));
}
}  // namespace

bool deskew_with_trajectory(const Trajectory& poses, double stamp, std::vector<Vec3f>& points,
                            const std::vector<float>& times) {
  if (poses.size() < 2 || !(stamp >= poses.front_stamp() && stamp <= poses.back_stamp())) return false;
  const Pose T_world_stamp_inv = trajectory_pose_at(poses, stamp).inverse();
  points = localization::deskew_scan(points, times, [&](double dt) {
    return T_world_stamp_inv * trajectory_pose_at(poses, stamp + dt);
  });
  return true;
}

void deskew_with_sweep(const localization::SweepMotion& sweep, std::vector<Vec3f>& points,
                       const std::vector<float>& times) {
  points = localization::deskew_scan(points, times, [&](double t) { return sweep.T_mid_sensor(t); });
}

}  // namespace slamvdb
