#pragma once
// Re-expressing one submap's voxels in another's frame: merging two submaps that a loop closure
// shows to be the same place, and combining the occupancy of overlapping submaps in the world.
//
// Resampling rule (both): each known voxel of the source is moved by its centre into the target
// grid and lands in the target voxel containing that point (nearest-centre resampling). Source
// voxels that land in the same target voxel are combined first: their log-odds by the maximum
// (within one map, a hit wins, as in OctoMap's per-scan rule) and their semantic entries by the
// mean weighted by their observations' weight sums (their counts under the paper's rule), counts
// summed, statistics combined (Chan's rule). The result is then combined with the target: log-odds
// added and clamped (independent evidence), semantic entries by the same weighted mean (Eq. 6.1
// generalised to two counts). Single-view layers (a baseline) keep the entry of larger weight.
// A combined entry's last-observed session is the newest of its parts' (SessionOrder).
#include <cstdint>
#include <string>
#include <vector>

#include "slamvdb/map/session_info.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

// Fraction of the occupied voxels of the smaller map that, moved into the target grid, land on
// occupied target voxels.
double occupied_overlap(const VoxelMap& target, const VoxelMap& source, const Pose& T_target_source);

struct MergeReport {
  bool merged = false;
  std::string refused;  // why not, when not merged
  double overlap = 0.0;
  std::size_t source_known = 0, target_known_before = 0, target_known_after = 0;
  std::size_t semantic_entries_before = 0;  // source + target
  std::size_t semantic_entries_after = 0;
  uint64_t counts_before = 0;   // summed observation counts, source + target
  uint64_t counts_after = 0;
  uint64_t counts_dropped_free = 0;  // counts of entries whose voxel ended up free (not lost silently)
  std::size_t entries_dropped_free = 0;
};

// Merges `source` into `target` (both in their own frames; T_target_source moves source points
// into the target frame). Does not check the overlap; SemanticMap::merge_submaps does. `sessions`
// orders the entries' last-observed sessions (default: the larger id is the newer).
MergeReport merge_into(VoxelMap& target, const VoxelMap& source, const Pose& T_target_source,
                       const SessionOrder& sessions = {});

// One cell of the world occupancy: summed (clamped) log-odds of every submap's voxels in it.
struct WorldOccupancyCell {
  IndexCellKey cell;
  float log_odds;
};
struct PlacedVoxelMap {
  const VoxelMap* voxels;
  Pose T_world_submap;
};
// The occupancy of all submaps on the world grid (cell_size), by the rule above; every known
// cell, sorted by key. occupied: log_odds >= params.occupied_threshold.
std::vector<WorldOccupancyCell> combine_occupancy(const std::vector<PlacedVoxelMap>& submaps, double cell_size,
                                                  const OccupancyParams& params);

}  // namespace slamvdb
