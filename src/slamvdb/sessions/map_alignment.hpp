#pragma once
// Aligning two maps (SemanticMap) of different sessions, as `slamvdb align` does it: refuse maps
// that cannot share a world (different voxel sizes, embedding spaces or ontologies), align the
// other map's submaps to the base's (session_alignment.hpp), correct the other map's anchors
// with the joint graph (joint_graph.hpp) and set them (SemanticMap::set_submap_poses: no
// re-integration). Knows nothing of files.
#include <map>
#include <string>

#include "slamvdb/core/types.hpp"
#include "slamvdb/sessions/session_alignment.hpp"

namespace slamvdb {
class SemanticMap;
struct MapParams;
struct MapInfo;
}  // namespace slamvdb

namespace slamvdb::sessions {

// Empty when two maps can be aligned and merged; else a sentence naming the first difference and
// both values (voxel size, model id, ontology, embedding dimension). Reads parameters only, so
// a caller can check before loading the voxels.
std::string map_incompatibility(const MapParams& base_params, const MapInfo& base_info, const MapParams& other_params,
                                const MapInfo& other_info);

struct MapAlignment {
  SessionAlignment alignment;
  // When aligned: every submap of the other map, its anchor before (its own world) and after
  // (the base's world, graph-corrected), by id.
  std::map<int, Pose> anchors_before, anchors_after;
  // With --adjust-base (align_maps_adjusting_base), the base map's anchors likewise; else empty.
  std::map<int, Pose> base_anchors_before, base_anchors_after;
};

// Aligns `other` to `base`; when aligned, moves `other`'s submap anchors into the base's world
// (set_submap_poses). When refused (alignment.refused), `other` is unchanged. Throws Error for
// incompatible maps (map_incompatibility) or an invalid config.
MapAlignment align_maps(const SemanticMap& base, SemanticMap& other, const AlignmentConfig& config = {});

// align_maps, then both maps' anchors corrected by one joint graph over both sessions' submaps
// (correct_both_anchors: the base's first submap fixed) and set on both (`align --adjust-base`).
// When refused, neither map changes.
MapAlignment align_maps_adjusting_base(SemanticMap& base, SemanticMap& other, const AlignmentConfig& config = {});

}  // namespace slamvdb::sessions
