#pragma once
// Scan pre-processing for the tracker: invalid-point removal (counted), motion compensation
// ("deskewing") and voxel downsampling.
#include <cstddef>
#include <functional>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::localization {

struct PointFilterStats {
  std::size_t input = 0;
  std::size_t non_finite = 0;    // a NaN or inf coordinate (or NaN time)
  std::size_t out_of_range = 0;  // closer than min_range (incl. (0,0,0) no-return points) or beyond max_range
  std::size_t kept() const { return input - non_finite - out_of_range; }
};

// Points (as double) whose range lies in [min_range, max_range]; when `times` is given, the
// per-point times of the kept points are written to `kept_times` (same order).
std::vector<Vec3d> filter_points(const std::vector<Vec3f>& points, double min_range, double max_range,
                                 PointFilterStats& stats, const std::vector<float>* times = nullptr,
                                 std::vector<double>* kept_times = nullptr);

// The sensor's motion over one sweep under constant velocity, as the odometry estimates it (its
// last motion between scans): `delta` = T_start_end from the earliest to the latest point time.
struct SweepMotion {
  Pose delta = Pose::Identity();
  double time_begin = 0.0, time_end = 0.0;  // earliest and latest point time (as given)
  // Where the sensor was at point time `time`, seen from its frame at mid-sweep (times outside the
  // sweep clamped to it; a sweep without duration: the identity).
  Pose T_mid_sensor(double time) const;
};
// The sweep of points with `times` (any unit and offset) moving by `delta` over it.
SweepMotion sweep_motion(const std::vector<double>& times, const Pose& delta);

// Motion compensation under constant velocity: every point is moved into the sensor frame at the
// middle of the sweep, as KISS-ICP does, so the scan's pose refers to the mid-sweep instant.
std::vector<Vec3d> deskew(const std::vector<Vec3d>& points, const std::vector<double>& times, const SweepMotion& motion);

// Motion compensation of a whole scan as read (the mapping's): every point moves into the sensor
// frame of one reference instant, `T_ref_sensor(t)` being where the sensor was at point time t
// seen from that frame. Points whose coordinates or time are not finite stay as they are (the
// mapper counts non-finite points; a finite point without a finite time is kept as read).
std::vector<Vec3f> deskew_scan(const std::vector<Vec3f>& points, const std::vector<float>& times,
                               const std::function<Pose(double)>& T_ref_sensor);

// One point per voxel of edge `voxel_size` (the first one met, so the result is deterministic).
std::vector<Vec3d> voxel_downsample(const std::vector<Vec3d>& points, double voxel_size);

}  // namespace slamvdb::localization
