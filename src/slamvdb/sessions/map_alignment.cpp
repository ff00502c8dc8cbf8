#include "slamvdb/sessions/map_alignment.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/sessions/joint_graph.hpp"
#include "slamvdb/sessions/session_submaps.hpp"

namespace slamvdb::sessions {

std::string map_incompatibility(const MapParams& base_params, const MapInfo& base_info, const MapParams& other_params,
                                const MapInfo& other_info) {
  if (base_params.occupancy.voxel_size != other_params.occupancy.voxel_size)
    return fmt::format("the maps have different voxel sizes: base {} m, other {} m", base_params.occupancy.voxel_size,
                       other_params.occupancy.voxel_size);
  if (base_info.model_id != other_info.model_id)
    return fmt::format("the maps are in different embedding spaces: base model id '{}', other '{}'", escape_control(base_info.model_id),
                       escape_control(other_info.model_id));
  if (base_params.semantic.dim != other_params.semantic.dim)
    return fmt::format("the maps have different embedding dimensions: base {}, other {}", base_params.semantic.dim,
                       other_params.semantic.dim);
  if (base_info.ontology != other_info.ontology)
    return fmt::format("the maps use different ontologies: base '{}', other '{}'", escape_control(base_info.ontology),
                       escape_control(other_info.ontology));
  return {};
}

namespace {

MapAlignment align(const SemanticMap& base, SemanticMap& other, const AlignmentConfig& config, SemanticMap* adjust_base) {
  const std::string incompatible = map_incompatibility(base.params(), base.info(), other.params(), other.info());
  if (!incompatible.empty()) throw Error(incompatible);
  const std::vector<SessionSubmap> base_submaps = session_submaps(base), other_submaps = session_submaps(other);
  MapAlignment out;
  out.alignment = align_sessions(base_submaps, other_submaps, config);
  if (!out.alignment.aligned) return out;
  for (const SessionSubmap& s : other_submaps) out.anchors_before[s.id] = s.T_world_submap;
  if (adjust_base) {
    JointCorrection both = correct_both_anchors(base_submaps, other_submaps, out.alignment);
    for (const SessionSubmap& s : base_submaps) out.base_anchors_before[s.id] = s.T_world_submap;
    out.anchors_after = std::move(both.other);
    out.base_anchors_after = std::move(both.base);
    other.set_submap_poses(out.anchors_after);
    adjust_base->set_submap_poses(out.base_anchors_after);
  } else {
    out.anchors_after = correct_other_anchors(other_submaps, out.alignment);
    other.set_submap_poses(out.anchors_after);
  }
  return out;
}

}  // namespace

MapAlignment align_maps(const SemanticMap& base, SemanticMap& other, const AlignmentConfig& config) {
  return align(base, other, config, nullptr);
}

MapAlignment align_maps_adjusting_base(SemanticMap& base, SemanticMap& other, const AlignmentConfig& config) {
  return align(base, other, config, &base);
}

}  // namespace slamvdb::sessions
