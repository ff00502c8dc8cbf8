#pragma once
// Loop closure applied to submaps while mapping goes on (paper section 6.2.1): when the pose graph
// is corrected, every submap's anchor moves by the new correction at the submap's time (no sensor
// data is integrated again), and two finished submaps that an accepted loop joins and that overlap
// are merged.
//
// The mapper is given poses in the corrected world as it was known at the time: poses given
// before a correction carry the older one, and so does every submap anchored on them. This class
// remembers which correction each submap's anchor holds, so a new correction replaces it instead
// of being applied on top.
#include <cstddef>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

struct LoopCorrectionReport {
  std::size_t corrections = 0;     // times the submaps were moved
  std::size_t submaps_moved = 0;   // distinct submaps moved at least once
  double max_shift = 0.0;          // metres, largest anchor displacement of one move
  std::size_t merges = 0, merges_refused = 0;
  std::vector<std::string> notes;  // one line per merge or refusal
};

// A correction maps the world as the poses were given into the corrected world:
// K = T_world_corrected_world_given, a function of the stamp.
using CorrectionFn = std::function<Pose(double stamp)>;

class SubmapCorrections {
 public:
  // Poses with stamps from `from_stamp` on are given to the mapper with `correction` already in them.
  void poses_given_with(double from_stamp, const Pose& correction);
  // The anchors that move `submaps` to `correction` (taken at the middle of each submap's time
  // range), which are then remembered as applied.
  std::map<int, Pose> move(const std::vector<SubmapInfo>& submaps, const CorrectionFn& correction);

  // An accepted loop between the scans at these stamps: their submaps are to be merged.
  void add_loop(double candidate_stamp, double query_stamp);
  // Tries to merge the submaps of every pending loop whose two submaps are known and not `active`
  // (merge(target, source) does it); each pair is tried once, a merged-away submap is followed to
  // the one that absorbed it.
  void merge_ready(const std::vector<SubmapInfo>& submaps, std::optional<int> active,
                   const std::function<MergeReport(int target, int source)>& merge);
  std::size_t pending_loops() const { return pending_.size(); }

  const LoopCorrectionReport& report() const { return report_; }

 private:
  void note_ranges(const std::vector<SubmapInfo>& submaps);
  Pose given_at(double stamp) const;
  std::optional<int> submap_at(double stamp) const;
  int resolve(int id) const;

  std::vector<std::pair<double, Pose>> given_;  // (from stamp, correction), stamps increasing
  std::map<int, Pose> applied_;                 // the correction each submap's anchor holds
  // Every submap seen, with its own time range: kept as it was when the submap finished (a merge
  // widens the target's range over the submaps between the two).
  std::map<int, std::pair<TimeRange, bool /*finished*/>> ranges_;
  std::map<int, int> absorbed_by_;
  std::set<int> moved_ids_;
  std::vector<std::pair<double, double>> pending_;
  std::vector<std::pair<int, int>> tried_;
  LoopCorrectionReport report_;
};

}  // namespace slamvdb
