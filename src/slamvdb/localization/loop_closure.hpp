#pragma once
// The loop-closing mapper: keyframes every few metres of odometry path, loop candidates from
// ScanContext (seeded with its yaw) and from proximity in the current estimate (far along the
// path), verification by robust ICP against the candidate's local map with an overlap, a fitness
// (inlier RMSE) and an odometry-consistency test, and SE(3) pose-graph optimisation after every
// accepted loop. Its output is the correction T_world_odom at any time stamp, so a mapper can move
// whatever it anchored to odometry poses (submaps) to the corrected trajectory.
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/localization/pose_graph.hpp"
#include "slamvdb/localization/scan_context.hpp"

namespace slamvdb::localization {

struct LoopClosureConfig {
  double keyframe_distance = 2.0;  // metres of odometry path between keyframes
  ScanContextConfig scan_context;
  std::size_t ring_key_neighbours = 10;   // k-d tree candidates re-ranked by the full descriptor
  double max_scan_context_distance = 0.35;  // cosine distance to try a ScanContext candidate
  std::size_t max_scan_context_candidates = 2;
  double min_loop_path = 30.0;    // metres along the path between the two ends of a loop
  double proximity_radius = 8.0;  // metres in the current estimate for a proximity candidate
  // Verification.
  double keyframe_voxel = 0.5;         // keyframe clouds are kept at this resolution ...
  double keyframe_range = 50.0;        // ... and within this range
  int local_map_neighbours = 2;        // keyframes on each side of the candidate form its local map
  double inlier_distance = 0.3;        // metres
  double min_overlap = 0.6;            // fraction of the query's points within inlier_distance
  // Metres, over those inliers; with 0.5 m keyframe clouds a correct alignment gives ~0.15 m.
  double max_rmse = 0.2;
  // The loop may not move the query farther from the odometry estimate than this (odometry
  // drifts by a fraction of the path); rejects look-alike places far apart.
  double max_drift_fraction = 0.05;  // of the path between the two keyframes
  double min_drift_allowance = 3.0;  // metres
  double max_rotation_drift = 0.005; // radians per metre of path (at least 0.3 rad)
  // Pose-graph weights: odometry standard deviations grow with the distance between keyframes.
  double odometry_sigma_translation = 0.02, odometry_sigma_translation_per_m = 0.01;
  double odometry_sigma_rotation = 0.002, odometry_sigma_rotation_per_m = 0.0005;
  double prediction_sigma_scale = 10.0;  // for intervals containing scans the odometry only predicted
  double loop_sigma_translation = 0.1, loop_sigma_rotation = 0.01;
  PoseGraphOptions pose_graph;
  void validate() const;
};

enum class LoopRejection { kIcpFailed, kLowOverlap, kHighRmse, kInconsistentWithOdometry, kCount };
const char* to_string(LoopRejection reason);

struct LoopClosure {
  std::size_t candidate_keyframe = 0, query_keyframe = 0;
  double candidate_stamp = 0.0, query_stamp = 0.0;
  Pose T_candidate_query = Pose::Identity();  // verified relative pose of the two keyframes' sensor frames
  double overlap = 0.0;                       // fraction of query points on the candidate's local map
  double rmse = 0.0;                          // metres, over those points
  double scan_context_distance = -1.0;        // -1 for a proximity candidate
  bool from_scan_context = false;
};

struct LoopAttempt {
  std::size_t candidate_keyframe = 0;
  bool from_scan_context = false;
  bool accepted = false;
  LoopRejection rejection = LoopRejection::kIcpFailed;  // when not accepted
  double overlap = 0.0, rmse = 0.0;
};

struct AddScanResult {
  bool keyframe = false;
  std::size_t keyframe_index = 0;    // when keyframe
  std::vector<LoopAttempt> attempts; // loop candidates verified for this keyframe
  bool optimized = false;            // the pose graph was re-optimised (an accepted loop)
};

struct Keyframe {
  double stamp = 0.0;
  Pose T_odom_sensor = Pose::Identity();
  Pose T_world_sensor = Pose::Identity();  // corrected
  double path_distance = 0.0;              // odometry path length at this keyframe
};

class LoopClosingMapper {
 public:
  explicit LoopClosingMapper(LoopClosureConfig config = {});

  // Feeds one odometry result (stamps strictly increasing). `pose_is_prediction` marks a scan the
  // odometry could not register (its interval gets a wider uncertainty and it is never a keyframe).
  AddScanResult add_scan(double stamp, const Pose& T_odom_sensor, const std::vector<Vec3f>& points_sensor,
                         bool pose_is_prediction = false);

  // T_world_odom at `stamp`: the keyframe corrections interpolated on SE(3) between the two
  // neighbouring keyframes, held constant before the first and after the last keyframe.
  Pose correction_at(double stamp) const;
  Pose corrected_pose(double stamp, const Pose& T_odom_sensor) const {
    return correction_at(stamp) * T_odom_sensor;
  }

  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  const std::vector<LoopClosure>& loops() const { return loops_; }
  const std::array<std::size_t, static_cast<std::size_t>(LoopRejection::kCount)>& rejections() const {
    return rejections_;
  }
  std::size_t rejected_total() const;
  std::size_t optimizations() const { return optimizations_; }
  const LoopClosureConfig& config() const { return config_; }

 private:
  struct Candidate {
    std::size_t keyframe;
    Pose T_candidate_query_guess;
    bool from_scan_context;
    double scan_context_distance;
  };
  std::vector<Candidate> find_candidates(std::size_t query, const ScanContext& context) const;
  LoopAttempt verify(std::size_t query, const Candidate& candidate, LoopClosure& loop) const;
  void optimize();

  LoopClosureConfig config_;
  ScanContextDatabase database_;
  PoseGraph graph_;
  std::vector<Keyframe> keyframes_;
  std::vector<std::vector<Vec3f>> keyframe_points_;  // sensor frame, downsampled
  std::vector<LoopClosure> loops_;
  std::array<std::size_t, static_cast<std::size_t>(LoopRejection::kCount)> rejections_{};
  std::size_t optimizations_ = 0;
  double path_distance_ = 0.0;
  bool have_last_ = false;
  double last_stamp_ = 0.0;
  Pose last_T_odom_ = Pose::Identity();
  bool interval_has_prediction_ = false;
};

}  // namespace slamvdb::localization
