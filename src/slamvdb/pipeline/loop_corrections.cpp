#include "slamvdb/pipeline/loop_corrections.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace slamvdb {

void SubmapCorrections::poses_given_with(double from_stamp, const Pose& correction) {
  while (!given_.empty() && given_.back().first >= from_stamp) given_.pop_back();
  given_.emplace_back(from_stamp, correction);
}

Pose SubmapCorrections::given_at(double stamp) const {
  Pose K = Pose::Identity();  // before any correction was given
  for (const auto& [from, correction] : given_)
    if (from <= stamp) K = correction;
  return K;
}

void SubmapCorrections::note_ranges(const std::vector<SubmapInfo>& submaps) {
  for (const SubmapInfo& s : submaps) {
    auto& [range, finished] = ranges_[s.id];
    if (!finished) range = s.time_range, finished = s.finished;
  }
}

std::map<int, Pose> SubmapCorrections::move(const std::vector<SubmapInfo>& submaps, const CorrectionFn& correction) {
  note_ranges(submaps);
  std::map<int, Pose> moved;
  for (const SubmapInfo& s : submaps) {
    if (s.time_range.empty()) continue;
    // A submap first seen holds the correction its anchoring pose (its first stamp) was given with.
    const Pose held = applied_.contains(s.id) ? applied_.at(s.id) : given_at(s.time_range.begin);
    // The correction changes along the submap's time; its middle stands for all of it (the drift
    // inside one submap remains).
    const Pose K = correction(0.5 * (s.time_range.begin + s.time_range.end));
    const Pose T = K * held.inverse() * s.T_world_submap;
    report_.max_shift = std::max(report_.max_shift, (T.translation() - s.T_world_submap.translation()).norm());
    if ((T.matrix() - s.T_world_submap.matrix()).norm() > 1e-12) moved_ids_.insert(s.id);
    applied_[s.id] = K;
    moved.emplace(s.id, T);
  }
  ++report_.corrections;
  report_.submaps_moved = moved_ids_.size();
  return moved;
}

void SubmapCorrections::add_loop(double candidate_stamp, double query_stamp) {
  pending_.emplace_back(candidate_stamp, query_stamp);
}

std::optional<int> SubmapCorrections::submap_at(double stamp) const {
  for (const auto& [id, entry] : ranges_)
    if (const TimeRange& range = entry.first; !range.empty() && stamp >= range.begin && stamp <= range.end) return id;
  return std::nullopt;
}

int SubmapCorrections::resolve(int id) const {
  while (absorbed_by_.contains(id)) id = absorbed_by_.at(id);
  return id;
}

void SubmapCorrections::merge_ready(const std::vector<SubmapInfo>& submaps, std::optional<int> active,
                                    const std::function<MergeReport(int, int)>& merge) {
  note_ranges(submaps);
  std::vector<std::pair<double, double>> still_pending;
  for (const auto& loop : pending_) {
    const auto a = submap_at(loop.first), b = submap_at(loop.second);
    if (!a || !b || (active && (resolve(*a) == *active || resolve(*b) == *active))) {
      still_pending.push_back(loop);  // a submap not started or still being written
      continue;
    }
    const int target = resolve(*a), source = resolve(*b);
    if (target == source || std::find(tried_.begin(), tried_.end(), std::pair{target, source}) != tried_.end()) continue;
    tried_.emplace_back(target, source);
    const MergeReport r = merge(target, source);
    if (r.merged) {
      ++report_.merges;
      absorbed_by_[source] = target;
      report_.notes.push_back(fmt::format("submap {} merged into {} (overlap {:.2f})", source, target, r.overlap));
    } else {
      ++report_.merges_refused;
      report_.notes.push_back(fmt::format("submaps {} and {} not merged: {}", target, source, r.refused));
    }
  }
  pending_ = std::move(still_pending);
}

}  // namespace slamvdb
