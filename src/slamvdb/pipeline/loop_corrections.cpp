#include "slamvdb/pipeline/loop_corrections.hpp"

#include <fmt/format.h>

#include <map>
#include <optional>
#include <set>

namespace slamvdb {
namespace {

std::optional<int> submap_at(const std::vector<SubmapInfo>& submaps, double stamp) {
  for (const SubmapInfo& s : submaps)
    if (!s.time_range.empty() && stamp >= s.time_range.begin && stamp <= s.time_range.end) return s.id;
  return std::nullopt;
}

}  // namespace

LoopCorrectionReport apply_loop_corrections(SemanticMap& map, const std::function<Pose(double)>& correction,
                                            const std::vector<std::pair<double, double>>& loops,
                                            const MergeOptions& merge_options) {
  LoopCorrectionReport report;
  const std::vector<SubmapInfo> submaps = map.submaps();
  // The correction at the middle of a submap's time: its data spans that range, and the
  // correction changes along it (the drift inside one submap remains).
  std::map<int, Pose> moved;
  for (const SubmapInfo& s : submaps) {
    const double t = s.time_range.empty() ? 0.0 : 0.5 * (s.time_range.begin + s.time_range.end);
    const Pose T = correction(t) * s.T_world_submap;
    report.max_shift = std::max(report.max_shift, (T.translation() - s.T_world_submap.translation()).norm());
    moved.emplace(s.id, T);
  }
  map.set_submap_poses(moved);
  report.submaps_moved = moved.size();

  // Merges: the submaps holding the two ends of each loop, once per pair; a submap merged away is
  // followed to the one that absorbed it.
  std::map<int, int> absorbed_by;
  const auto resolve = [&](int id) {
    while (absorbed_by.count(id)) id = absorbed_by.at(id);
    return id;
  };
  std::set<std::pair<int, int>> tried;
  for (const auto& [candidate_stamp, query_stamp] : loops) {
    const auto a = submap_at(submaps, candidate_stamp), b = submap_at(submaps, query_stamp);
    if (!a || !b) continue;
    const int target = resolve(*a), source = resolve(*b);
    if (target == source || !tried.insert({target, source}).second) continue;
    const MergeReport r = map.merge_submaps(target, source, merge_options);
    if (r.merged) {
      ++report.merges;
      absorbed_by[source] = target;
      report.notes.push_back(fmt::format("submap {} merged into {} (overlap {:.2f})", source, target, r.overlap));
    } else {
      ++report.merges_refused;
      report.notes.push_back(fmt::format("submaps {} and {} not merged: {}", target, source, r.refused));
    }
  }
  return report;
}

}  // namespace slamvdb
