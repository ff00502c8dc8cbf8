// `slamvdb info`: what a map file holds (counts, sizes, submaps, parameters, model), read from its
// metadata without loading the voxels.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <nlohmann/json.hpp>

#include "command_registry.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli {
namespace {

struct Options {
  std::string map;
  bool json = false;
};

// Roll, pitch, yaw (ZYX convention) in degrees; "+ 0.0" turns -0 into 0 for printing.
Eigen::Vector3d rpy_degrees(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  const double rad = 180.0 / M_PI;
  return Eigen::Vector3d(std::atan2(R(2, 1), R(2, 2)), std::asin(std::clamp(-R(2, 0), -1.0, 1.0)),
                         std::atan2(R(1, 0), R(0, 0))) * rad +
         Eigen::Vector3d::Zero();
}

double per_voxel(uint64_t bytes, std::size_t voxels) { return voxels ? static_cast<double>(bytes) / voxels : 0.0; }

nlohmann::json to_json(const std::string& path, const MapFileSummary& s) {
  nlohmann::json submaps = nlohmann::json::array();
  for (const SubmapSummary& sm : s.submaps) {
    const Eigen::Matrix4d m = sm.T_world_submap.matrix();
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
    const Eigen::Vector3d t = sm.T_world_submap.translation(), rpy = rpy_degrees(sm.T_world_submap);
    submaps.push_back({{"id", sm.id},
                       {"T_world_submap", rows},
                       {"translation", {t.x(), t.y(), t.z()}},
                       {"rpy_deg", {rpy.x(), rpy.y(), rpy.z()}},
                       {"blocks", sm.blocks},
                       {"known_voxels", sm.known_voxels},
                       {"occupied_voxels", sm.occupied_voxels},
                       {"semantic_voxels", sm.semantic_voxels}});
  }
  return {{"path", path},
          {"format_version", s.format_version},
          {"voxels", {{"known", s.known_voxels}, {"occupied", s.occupied_voxels}, {"semantic", s.semantic_voxels}}},
          {"bytes",
           {{"file", s.file_bytes},
            {"in_memory_at_save", s.memory_bytes},
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
          {"submaps", submaps}};
}

std::string megabytes(uint64_t bytes) { return fmt::format("{:.1f} MB", static_cast<double>(bytes) / 1e6); }

void print_text(const std::string& path, const MapFileSummary& s) {
  fmt::print("map        {} (format version {})\n", path, s.format_version);
  fmt::print("voxels     {} known, {} occupied (voxel size {} m)\n", s.known_voxels, s.occupied_voxels,
             s.params.occupancy.voxel_size);
  fmt::print("semantics  {} semantic voxels, {}-d {} embeddings\n", s.semantic_voxels, s.params.semantic.dim,
             to_string(s.params.semantic.precision));
  // Text from the map file, printed with control characters escaped (core/text_escape.hpp).
  fmt::print("model      {}\n", s.info.model_id.empty() ? "(none)" : escape_control(s.info.model_id));
  fmt::print("ontology   {}\n", escape_control(s.info.ontology));
  fmt::print("source     {}\n", s.info.source.empty() ? "(not recorded)" : escape_control(s.info.source));
  fmt::print("bytes      file {}, in memory {} (when saved)\n", megabytes(s.file_bytes), megabytes(s.memory_bytes));
  fmt::print("           on disk: occupancy {}, semantics {}", megabytes(s.occupancy_payload_bytes),
             megabytes(s.semantic_payload_bytes));
  if (s.semantic_voxels)
    fmt::print(" = {:.0f} B per semantic voxel (whole file: {:.0f} B)", per_voxel(s.semantic_payload_bytes, s.semantic_voxels),
               per_voxel(s.file_bytes, s.semantic_voxels));
  fmt::print("\nsubmaps    {}\n", s.submaps.size());
  for (const SubmapSummary& sm : s.submaps) {
    const Eigen::Vector3d t = sm.T_world_submap.translation(), rpy = rpy_degrees(sm.T_world_submap);
    fmt::print("  id {:<5} t = ({:.3f}, {:.3f}, {:.3f}) m  rpy = ({:.2f}, {:.2f}, {:.2f}) deg  {} known, {} occupied, "
               "{} semantic voxels\n",
               sm.id, t.x(), t.y(), t.z(), rpy.x(), rpy.y(), rpy.z(), sm.known_voxels, sm.occupied_voxels,
               sm.semantic_voxels);
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand("info", "Show what a map file holds: voxel counts, sizes, submaps and poses, "
                                          "voxel size, embedding dimension and precision, model, ontology, source");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required();
  cmd->add_flag("--json", opt->json, "Print JSON instead of text");
  cmd->callback([opt] {
    const MapFileSummary s = read_map_summary(opt->map);
    if (opt->json) fmt::print("{}\n", to_json(opt->map, s).dump(2, ' ', true, nlohmann::json::error_handler_t::replace));
    else print_text(opt->map, s);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli
