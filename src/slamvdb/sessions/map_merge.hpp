#pragma once
// Merging maps of different sessions into one (`slamvdb merge`): every input's submaps, with new
// ids in one id space, each still in the session it was mapped in (the sessions renumbered, kept
// in input order). The inputs must already share one world (`slamvdb align`); submaps of
// different sessions that cover the same place are merged where they overlap enough
// (session_overlap_merge.hpp: the loop closer's rule, every voxel once). Knows nothing of files.
#include <cstdint>
#include <string>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/sessions/session_overlap_merge.hpp"

namespace slamvdb::sessions {

// Empty when maps can be merged into one: map_incompatibility (voxel size, model id, embedding
// dimension, ontology) and the occupancy settings (log-odds hit and miss, clamping, threshold),
// which the merged map's world occupancy sums under; else a sentence naming the first
// difference and both values.
std::string merge_incompatibility(const MapParams& first_params, const MapInfo& first_info, const MapParams& params,
                                  const MapInfo& info);

// What one map holds, as a merge counts it.
struct MapContents {
  std::size_t sessions = 0, submaps = 0;
  std::size_t occupied_voxels = 0, semantic_voxels = 0;
  uint64_t observations = 0;  // the semantic voxels' view counts, summed
  MapContents& operator+=(const MapContents& o);
  bool operator==(const MapContents&) const = default;
};
MapContents map_contents(const SemanticMap& map);

struct MapMergeReport {
  std::vector<MapContents> inputs;
  MapContents merged;
  std::vector<SubmapAbsorption> absorbed;  // the merges of overlapping submaps, in order (merged ids)
};

// Moves every submap of `inputs` (left empty) into one map with the first input's parameters and
// info, its sessions those of all inputs (an input that lists none contributes one session named
// labels[i]); then merges overlapping submaps of different sessions (`overlap`). Throws Error
// naming labels[i] and the difference for an input that cannot be merged (merge_incompatibility),
// for fewer than two inputs, or when the merged map does not hold the inputs' contents count for
// count (report.merged == the sum of report.inputs less what report.absorbed combined or
// dropped). Deterministic.
SemanticMap merge_session_maps(std::vector<SemanticMap>& inputs, const std::vector<std::string>& labels,
                               MapMergeReport& report, const OverlapMergeOptions& overlap = {});

}  // namespace slamvdb::sessions
