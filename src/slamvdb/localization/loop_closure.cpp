#include "slamvdb/localization/loop_closure.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/se3.hpp"
#include "slamvdb/localization/preprocessing.hpp"
#include "slamvdb/localization/registration.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"

namespace slamvdb::localization {

void LoopClosureConfig::validate() const {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("invalid loop-closure setting: " + what);
  };
  require(keyframe_distance > 0.0, fmt::format("keyframe distance {} m must be > 0", keyframe_distance));
  require(min_loop_path > keyframe_distance, "min loop path must exceed the keyframe distance");
  require(keyframe_voxel > 0.0 && keyframe_range > 0.0, "keyframe voxel and range must be > 0");
  require(min_overlap > 0.0 && min_overlap <= 1.0, fmt::format("min overlap {} must be in (0, 1]", min_overlap));
  require(max_rmse > 0.0 && inlier_distance > 0.0, "max RMSE and inlier distance must be > 0");
  require(local_map_neighbours >= 0, "local map neighbours must be >= 0");
  scan_context.validate();
}

const char* to_string(LoopRejection reason) {
  switch (reason) {
    case LoopRejection::kIcpFailed: return "ICP failed";
    case LoopRejection::kLowOverlap: return "low overlap";
    case LoopRejection::kHighRmse: return "high RMSE";
    case LoopRejection::kInconsistentWithOdometry: return "inconsistent with odometry";
    case LoopRejection::kCount: break;
  }
  return "?";
}

LoopClosingMapper::LoopClosingMapper(LoopClosureConfig config)
    : config_((config.validate(), config)), database_(config.scan_context) {}

std::size_t LoopClosingMapper::rejected_total() const {
  std::size_t n = 0;
  for (const std::size_t r : rejections_) n += r;
  return n;
}

AddScanResult LoopClosingMapper::add_scan(double stamp, const Pose& T_odom_sensor,
                                          const std::vector<Vec3f>& points_sensor, bool pose_is_prediction) {
  if (have_last_ && !(stamp > last_stamp_))
    throw Error(fmt::format("loop closure: scan stamps must increase, but {:.6f} follows {:.6f}", stamp, last_stamp_));
  AddScanResult result;
  if (have_last_) path_distance_ += (T_odom_sensor.translation() - last_T_odom_.translation()).norm();
  have_last_ = true;
  last_stamp_ = stamp;
  last_T_odom_ = T_odom_sensor;
  interval_has_prediction_ |= pose_is_prediction;
  const bool due = keyframes_.empty() || path_distance_ - keyframes_.back().path_distance >= config_.keyframe_distance;
  if (!due || pose_is_prediction) return result;

  PointFilterStats stats;
  std::vector<Vec3d> points = voxel_downsample(
      filter_points(points_sensor, 0.5, config_.keyframe_range, stats), config_.keyframe_voxel);
  if (points.size() < 100) return result;  // nothing to recognise or verify; try the next scan

  Keyframe kf;
  kf.stamp = stamp;
  kf.T_odom_sensor = T_odom_sensor;
  kf.path_distance = path_distance_;
  kf.T_world_sensor = keyframes_.empty() ? T_odom_sensor : correction_at(stamp) * T_odom_sensor;
  const std::size_t index = keyframes_.size();
  graph_.add_vertex(kf.T_world_sensor);
  if (index > 0) {
    const Keyframe& prev = keyframes_.back();
    const double d = kf.path_distance - prev.path_distance;
    const double scale = interval_has_prediction_ ? config_.prediction_sigma_scale : 1.0;
    graph_.add_edge({index - 1, index, prev.T_odom_sensor.inverse() * T_odom_sensor,
                     isotropic_information(
                         scale * (config_.odometry_sigma_translation + config_.odometry_sigma_translation_per_m * d),
                         scale * (config_.odometry_sigma_rotation + config_.odometry_sigma_rotation_per_m * d)),
                     false});
  }
  interval_has_prediction_ = false;
  keyframes_.push_back(kf);
  std::vector<Vec3f> stored(points.size());
  std::transform(points.begin(), points.end(), stored.begin(), [](const Vec3d& p) { return p.cast<float>(); });
  keyframe_points_.push_back(std::move(stored));
  ScanContext context = make_scan_context(points, config_.scan_context);
  result.keyframe = true;
  result.keyframe_index = index;

  // Candidates are looked up before this keyframe's descriptor joins the database.
  const std::vector<Candidate> candidates = find_candidates(index, context);
  database_.add(std::move(context));
  bool accepted = false;
  for (const Candidate& c : candidates) {
    LoopClosure loop;
    LoopAttempt attempt = verify(index, c, loop);
    result.attempts.push_back(attempt);
    if (!attempt.accepted) {
      ++rejections_[static_cast<std::size_t>(attempt.rejection)];
      continue;
    }
    loops_.push_back(loop);
    graph_.add_edge({loop.candidate_keyframe, loop.query_keyframe, loop.T_candidate_query,
                     isotropic_information(config_.loop_sigma_translation, config_.loop_sigma_rotation), true});
    accepted = true;
    break;  // one verified loop per keyframe is enough to correct the graph
  }
  if (accepted) {
    optimize();
    result.optimized = true;
  }
  return result;
}

std::vector<LoopClosingMapper::Candidate> LoopClosingMapper::find_candidates(std::size_t query,
                                                                           const ScanContext& context) const {
  const Keyframe& q = keyframes_[query];
  // Keyframes at least min_loop_path behind along the path form a prefix of the list.
  std::size_t eligible_end = 0;
  while (eligible_end < query && q.path_distance - keyframes_[eligible_end].path_distance >= config_.min_loop_path)
    ++eligible_end;
  std::vector<Candidate> out;
  if (eligible_end == 0) return out;
  const auto seen = [&](std::size_t k) {
    return std::any_of(out.begin(), out.end(), [&](const Candidate& c) { return c.keyframe == k; });
  };
  for (const auto& c : database_.query(context, eligible_end, config_.ring_key_neighbours,
                                       config_.max_scan_context_distance)) {
    if (out.size() >= config_.max_scan_context_candidates) break;
    Pose guess = Pose::Identity();  // ScanContext gives the yaw only
    guess.linear() = Eigen::AngleAxisd(c.match.yaw, Vec3d::UnitZ()).toRotationMatrix();
    out.push_back({c.index, guess, true, c.match.distance});
  }
  // The nearest keyframe in the current estimate, if close enough.
  double best = config_.proximity_radius;
  std::size_t nearest = eligible_end;
  for (std::size_t k = 0; k < eligible_end; ++k) {
    const double d = (keyframes_[k].T_world_sensor.translation() - q.T_world_sensor.translation()).norm();
    if (d < best) {
      best = d;
      nearest = k;
    }
  }
  if (nearest < eligible_end && !seen(nearest))
    out.push_back({nearest, keyframes_[nearest].T_world_sensor.inverse() * q.T_world_sensor, false, -1.0});
  return out;
}

LoopAttempt LoopClosingMapper::verify(std::size_t query, const Candidate& candidate, LoopClosure& loop) const {
  LoopAttempt attempt;
  attempt.candidate_keyframe = candidate.keyframe;
  attempt.from_scan_context = candidate.from_scan_context;
  const std::size_t c = candidate.keyframe;
  // The candidate's local map, fine and coarse: its neighbours' clouds placed by odometry, which
  // is exact enough over a few metres.
  VoxelHashMap fine(config_.keyframe_voxel, 1e9, 20), coarse(3.0 * config_.keyframe_voxel, 1e9, 20);
  const std::size_t lo = c >= static_cast<std::size_t>(config_.local_map_neighbours) ? c - config_.local_map_neighbours : 0;
  const std::size_t hi = std::min(query, c + config_.local_map_neighbours + 1);  // never the query's own neighbourhood
  const Pose T_c_odom = keyframes_[c].T_odom_sensor.inverse();
  for (std::size_t k = lo; k < hi; ++k) {
    const Pose T_c_k = T_c_odom * keyframes_[k].T_odom_sensor;
    std::vector<Vec3d> pts;
    pts.reserve(keyframe_points_[k].size());
    for (const Vec3f& p : keyframe_points_[k]) pts.push_back(T_c_k * p.cast<double>());
    fine.add_points(pts);
    coarse.add_points(pts);
  }
  std::vector<Vec3d> source;
  source.reserve(keyframe_points_[query].size());
  for (const Vec3f& p : keyframe_points_[query]) source.push_back(p.cast<double>());
  // Coarse to fine, since the guess may be metres off (ScanContext gives no translation).
  const std::optional<Pose> aligned =
      align_coarse_to_fine(source, coarse, fine, candidate.T_candidate_query_guess, config_.keyframe_voxel);
  if (!aligned) {
    attempt.rejection = LoopRejection::kIcpFailed;
    return attempt;
  }
  const Pose T = *aligned;
  const AlignmentQuality quality = alignment_quality(source, fine, T, config_.inlier_distance);
  attempt.overlap = quality.inlier_fraction();
  attempt.rmse = quality.inlier_rmse;
  if (attempt.overlap < config_.min_overlap) {
    attempt.rejection = LoopRejection::kLowOverlap;
    return attempt;
  }
  if (attempt.rmse > config_.max_rmse) {
    attempt.rejection = LoopRejection::kHighRmse;
    return attempt;
  }
  // Odometry consistency: how far the loop moves the query from where the estimate puts it.
  const Keyframe& kq = keyframes_[query];
  const Keyframe& kc = keyframes_[c];
  const Pose estimate = kc.T_world_sensor.inverse() * kq.T_world_sensor;
  const Pose disagreement = estimate.inverse() * T;
  const double path = kq.path_distance - kc.path_distance;
  const double allowed = std::max(config_.min_drift_allowance, config_.max_drift_fraction * path);
  const double allowed_rotation = std::max(0.3, config_.max_rotation_drift * path);
  if (disagreement.translation().norm() > allowed ||
      Eigen::AngleAxisd(disagreement.linear()).angle() > allowed_rotation) {
    attempt.rejection = LoopRejection::kInconsistentWithOdometry;
    return attempt;
  }
  attempt.accepted = true;
  loop.candidate_keyframe = c;
  loop.query_keyframe = query;
  loop.candidate_stamp = kc.stamp;
  loop.query_stamp = kq.stamp;
  loop.T_candidate_query = T;
  loop.overlap = attempt.overlap;
  loop.rmse = attempt.rmse;
  loop.from_scan_context = candidate.from_scan_context;
  loop.scan_context_distance = candidate.scan_context_distance;
  return attempt;
}

void LoopClosingMapper::optimize() {
  graph_.optimize(config_.pose_graph);
  for (std::size_t i = 0; i < keyframes_.size(); ++i) keyframes_[i].T_world_sensor = graph_.pose(i);
  ++optimizations_;
}

Pose LoopClosingMapper::correction_at(double stamp) const {
  if (keyframes_.empty()) return Pose::Identity();
  const auto correction = [&](std::size_t i) {
    return keyframes_[i].T_world_sensor * keyframes_[i].T_odom_sensor.inverse();
  };
  if (stamp <= keyframes_.front().stamp) return correction(0);
  if (stamp >= keyframes_.back().stamp) return correction(keyframes_.size() - 1);
  const auto it = std::upper_bound(keyframes_.begin(), keyframes_.end(), stamp,
                                   [](double t, const Keyframe& k) { return t < k.stamp; });
  const std::size_t i1 = static_cast<std::size_t>(it - keyframes_.begin()), i0 = i1 - 1;
  const double s = (stamp - keyframes_[i0].stamp) / (keyframes_[i1].stamp - keyframes_[i0].stamp);
  return interpolate_se3(correction(i0), correction(i1), s);
}

}  // namespace slamvdb::localization
