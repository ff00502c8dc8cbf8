#include "slamvdb/io/map_info_json.hpp"

#include <algorithm>
#include <cmath>

namespace slamvdb {

namespace map_info_json_detail {

nlohmann::json time_range_json(const TimeRange& t) {
  if (t.empty()) return nullptr;
  return {t.begin, t.end};
}

}  // namespace map_info_json_detail

std::map<int, std::size_t> submaps_per_session(const MapFileSummary& summary) {
  std::map<int, std::size_t> out;
  for (const SessionInfo& session : summary.info.sessions) out[session.id] = 0;
  for (const SubmapSummary& submap : summary.submaps) ++out[submap.info.session];
  return out;
}

double bytes_per_voxel(uint64_t bytes, std::size_t voxels) {
  return voxels ? static_cast<double>(bytes) / voxels : 0.0;
}

MapWorldFigures map_world_figures(const SemanticMap& map) {
  MapWorldFigures w;
  w.index_cells = map.num_index_cells();
  map.read_index([&](const GlobalIndex& index) {
    for (std::size_t i = 0; i < index.size(); ++i) w.index_cells_shared += index.refs(i).size() > 1;
  });
  const float threshold = map.params().occupancy.occupied_threshold;
  for (const WorldOccupancyCell& c : map.world_occupancy()) w.occupied_world_cells += c.log_odds >= threshold;
  return w;
}

Eigen::Vector3d rpy_degrees(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  const double rad = 180.0 / M_PI;
  return Eigen::Vector3d(std::atan2(R(2, 1), R(2, 2)), std::asin(std::clamp(-R(2, 0), -1.0, 1.0)),
                         std::atan2(R(1, 0), R(0, 0))) * rad +
         Eigen::Vector3d::Zero();
}

nlohmann::json map_info_json(const std::string& path, const MapFileSummary& s, const std::optional<MapWorldFigures>& world) {
  const auto per_voxel = bytes_per_voxel;
  nlohmann::json submaps = nlohmann::json::array();
  for (const SubmapSummary& sm : s.submaps) {
    const Pose& T = sm.info.T_world_submap;
    const Eigen::Matrix4d m = T.matrix();
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
    const Eigen::Vector3d t = T.translation(), rpy = rpy_degrees(T);
    submaps.push_back({{"id", sm.info.id},
                       {"session", sm.info.session},
                       {"T_world_submap", rows},
                       {"translation", {t.x(), t.y(), t.z()}},
                       {"rpy_deg", {rpy.x(), rpy.y(), rpy.z()}},
                       {"time_range", map_info_json_detail::time_range_json(sm.info.time_range)},
                       {"path_length", sm.info.path_length},
                       {"blocks", sm.blocks},
                       {"known_voxels", sm.known_voxels},
                       {"occupied_voxels", sm.occupied_voxels},
                       {"semantic_voxels", sm.semantic_voxels}});
  }
  const std::map<int, std::size_t> counts = submaps_per_session(s);
  nlohmann::json sessions = nlohmann::json::array();
  for (const SessionInfo& session : s.info.sessions)
    sessions.push_back({{"id", session.id},
                        {"name", session.name},
                        {"source", session.source},
                        {"robot", session.robot},
                        {"time_range", map_info_json_detail::time_range_json(session.time)},
                        {"submaps", counts.at(session.id)}});
  nlohmann::json j = {{"path", path},
          {"format_version", s.format_version},
          {"voxels", {{"known", s.known_voxels}, {"occupied", s.occupied_voxels}, {"semantic", s.semantic_voxels}}},
          {"bytes",
           {{"file", s.file_bytes},
            {"in_memory_at_save", s.memory_bytes ? nlohmann::json(s.memory_bytes) : nlohmann::json()},
            {"occupancy_payload", s.occupancy_payload_bytes},
            {"semantic_payload", s.semantic_payload_bytes},
            {"semantic_payload_per_semantic_voxel", per_voxel(s.semantic_payload_bytes, s.semantic_voxels)},
            {"file_per_semantic_voxel", per_voxel(s.file_bytes, s.semantic_voxels)}}},
          {"voxel_size", s.params.occupancy.voxel_size},
          {"embedding_dim", s.params.semantic.dim},
          {"precision", std::string(to_string(s.params.semantic.precision))},
          {"model_id", s.info.model_id},
          {"ontology", s.info.ontology},
          {"source", s.info.source},
          {"config", s.info.config},
          {"submap_length", s.params.submap_length},
          {"sessions", sessions},
          {"submaps", submaps}};
  if (world)
    j["check"] = {{"ok", true},
                  {"index_cells", world->index_cells},
                  {"index_cells_in_several_submaps", world->index_cells_shared},
                  {"occupied_world_cells", world->occupied_world_cells}};
  return j;
}

}  // namespace slamvdb
