#pragma once
// Trajectory accuracy: Umeyama SE(3) alignment (Eigen::umeyama, no scale), absolute trajectory
// error (ATE), relative pose error (RPE) between consecutive poses, and KITTI-style drift
// (translation % and rotation deg/m averaged over sub-sequences of fixed path lengths, as in the
// KITTI odometry devkit).
#include <cstddef>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::localization {

// Index pairs (estimate, ground truth) whose stamps differ by at most max_difference seconds,
// each ground-truth pose used once, nearest first; both stamp lists sorted ascending.
std::vector<std::pair<std::size_t, std::size_t>> associate_by_stamp(const std::vector<double>& estimate_stamps,
                                                                    const std::vector<double>& truth_stamps,
                                                                    double max_difference);

// T_truth_estimate minimising sum |truth_i - T * estimate_i|^2 over positions (rigid, no scale).
// Throws Error for fewer than 3 positions or mismatched sizes.
Pose align_umeyama(const std::vector<Pose>& estimate, const std::vector<Pose>& truth);

struct AteResult {
  std::size_t pairs = 0;
  double rmse = 0.0, mean = 0.0, median = 0.0, max = 0.0;  // metres
  Pose T_truth_estimate = Pose::Identity();               // the alignment applied
};
// Position errors after aligning the estimate to the truth (poses paired by index).
AteResult absolute_trajectory_error(const std::vector<Pose>& estimate, const std::vector<Pose>& truth);

struct RpeResult {
  std::size_t pairs = 0;
  double translation_rmse = 0.0;   // metres per step
  double rotation_rmse_deg = 0.0;  // degrees per step
};
// Errors of the relative motion between pose i and i + step.
RpeResult relative_pose_error(const std::vector<Pose>& estimate, const std::vector<Pose>& truth, std::size_t step = 1);

struct DriftResult {
  std::vector<double> lengths;        // path lengths of the sub-sequences (metres)
  std::size_t segments = 0;           // sub-sequences averaged
  double translation_percent = 0.0;   // mean of |translation error| / length, in %
  double rotation_deg_per_m = 0.0;    // mean of rotation error / length
};
// Segment lengths: KITTI's 100, 200, ..., 800 m where the ground-truth path is longer than the
// segment; on a path shorter than 200 m, 10%, 20%, ..., 50% of its length instead. Sub-sequences
// start every `start_step` poses (10, as in the devkit).
std::vector<double> drift_segment_lengths(double path_length);
DriftResult kitti_drift(const std::vector<Pose>& estimate, const std::vector<Pose>& truth, std::size_t start_step = 10);

double path_length(const std::vector<Pose>& poses);

}  // namespace slamvdb::localization
