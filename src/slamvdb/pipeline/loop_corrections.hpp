#pragma once
// Loop closure applied to a map that was built on odometry poses: every submap's anchor is moved
// by the loop-closing mapper's correction at the submap's time (no sensor data is integrated
// again), and two submaps that an accepted loop joins and that overlap are merged.
#include <cstddef>
#include <functional>
#include <utility>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

struct LoopCorrectionReport {
  std::size_t submaps_moved = 0;
  double max_shift = 0.0;  // metres, largest anchor displacement
  std::size_t merges = 0, merges_refused = 0;
  std::vector<std::string> notes;  // one line per merge or refusal
};

// correction(stamp) = T_world_corrected_world_odometry at that stamp (the map's world frame as the
// odometry placed it, to the corrected one). loops: pairs of scan stamps an accepted loop joins.
LoopCorrectionReport apply_loop_corrections(SemanticMap& map, const std::function<Pose(double)>& correction,
                                            const std::vector<std::pair<double, double>>& loops,
                                            const MergeOptions& merge_options = {});

}  // namespace slamvdb
