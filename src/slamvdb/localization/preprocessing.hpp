#pragma once
// Scan pre-processing for the tracker: invalid-point removal (counted), motion compensation
// ("deskewing") and voxel downsampling.
#include <cstddef>
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

// Motion compensation under constant velocity: `times` are the points' capture times normalised
// to [0, 1] over the sweep, `delta` is the sensor motion over one sweep (T_start_end). Every point
// is moved into the sensor frame at the middle of the sweep (time 0.5), as KISS-ICP does, so the
// scan's pose refers to the mid-sweep instant.
std::vector<Vec3d> deskew(const std::vector<Vec3d>& points, const std::vector<double>& times, const Pose& delta);

// Normalises raw per-point times to [0, 1] (min -> 0, max -> 1); all-equal times map to 0.5.
std::vector<double> normalise_times(const std::vector<double>& times);

// One point per voxel of edge `voxel_size` (the first one met, so the result is deterministic).
std::vector<Vec3d> voxel_downsample(const std::vector<Vec3d>& points, double voxel_size);

}  // namespace slamvdb::localization
