#pragma once
// Merging the submaps of different sessions that cover the same place (issue 23), by the loop
// closer's rule (map/submap_merge.hpp: counts add, embeddings combine by the count-weighted mean,
// log-odds add and clamp, every voxel once). Used by merge_session_maps (map_merge.hpp) on the
// submaps of maps that already share one world. Knows nothing of files.
//
// Sessions. A merged submap stays in the session of the submap it was merged into (the earlier
// one in the merged id order: the earlier input), and so do its time range and path length: a
// session's time range is the union of its submaps' ranges, and extending a submap's range by a
// later drive's stamps would make the earlier drive seem to last until then. The voxels hold
// every contributing session's evidence; which sessions went into which submap is reported
// (SubmapAbsorption), and each voxel keeps the newest session that observed it (its semantic
// entry's last-observed session: the newer of the two by SessionOrder). A submap's list of
// sessions is not stored yet (docs/multi-session-design.md).
#include <cstdint>
#include <utility>
#include <vector>

#include "slamvdb/map/session_info.hpp"
#include "slamvdb/map/submap.hpp"

namespace slamvdb::sessions {

// One submap merged into another of a different session.
struct SubmapAbsorption {
  int target_id = 0, source_id = 0;            // the source no longer exists afterwards
  int target_session = 0, source_session = 0;
  double overlap = 0;                          // occupied_overlap() when merged
  uint64_t observations_moved = 0;             // the source's view counts, summed
  uint64_t observations_dropped_free = 0;      // of entries whose voxel ended up free
  // Lost otherwise: a voxel's count reaching UINT32_MAX, or a voxel moved outside the extent.
  uint64_t observations_clipped = 0;
  std::size_t semantic_voxels_removed = 0;     // source + target before, minus after
  int64_t occupied_voxels_removed = 0;         // likewise (a place in both is now one voxel);
                                               // negative if added evidence made voxels occupied
};

struct OverlapMergeOptions {
  bool enabled = true;
  double min_overlap = 0.3;  // occupied_overlap() of the pair; the loop closer's default (MergeOptions)
};

// Merges, in place, every submap whose occupied voxels overlap those of an earlier submap of
// another session by at least options.min_overlap into the earlier one that it overlaps most
// (ties: the lower index); absorbed submaps leave `submaps`. Submaps are visited in their order,
// which must be deterministic (merge_session_maps: the merged ids). Submaps of one session are
// never merged with each other here (that is the loop closer's decision, made while mapping).
// `sessions` says which session is newer (the merged map's sessions' time ranges).
std::vector<SubmapAbsorption> merge_overlapping_sessions(std::vector<std::pair<SubmapInfo, VoxelMap>>& submaps,
                                                         const OverlapMergeOptions& options,
                                                         const SessionOrder& sessions = {});

}  // namespace slamvdb::sessions
