// `slamvdb info`: what a map file holds (counts, sizes, submaps, parameters, model), read from its
// metadata without loading the voxels; with --check, loaded and validated in full and read through
// the global index (world frame).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <nlohmann/json.hpp>

#include "command_registry.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_info {
namespace {

struct Options {
  std::string map;
  bool json = false;
  bool check = false;
};

// What only a full load can tell: the map read through the global index, in the world frame.
struct WorldFigures {
  std::size_t index_cells = 0, index_cells_shared = 0, occupied_world_cells = 0;
};

WorldFigures read_world(const std::string& path) {
  const SemanticMap map = load_map(path);
  WorldFigures w;
  w.index_cells = map.num_index_cells();
  map.read_index([&](const GlobalIndex& index) {
    for (std::size_t i = 0; i < index.size(); ++i) w.index_cells_shared += index.refs(i).size() > 1;
  });
  const float threshold = map.params().occupancy.occupied_threshold;
  for (const WorldOccupancyCell& c : map.world_occupancy()) w.occupied_world_cells += c.log_odds >= threshold;
  return w;
}

nlohmann::json time_range_json(const TimeRange& t) {
  if (t.empty()) return nullptr;
  return {t.begin, t.end};
}

// Roll, pitch, yaw (ZYX convention) in degrees; "+ 0.0" turns -0 into 0 for printing.
Eigen::Vector3d rpy_degrees(const Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  const double rad = 180.0 / M_PI;
  return Eigen::Vector3d(std::atan2(R(2, 1), R(2, 2)), std::asin(std::clamp(-R(2, 0), -1.0, 1.0)),
                         std::atan2(R(1, 0), R(0, 0))) * rad +
         Eigen::Vector3d::Zero();
}

double per_voxel(uint64_t bytes, std::size_t voxels) { return voxels ? static_cast<double>(bytes) / voxels : 0.0; }

nlohmann::json to_json(const std::string& path, const MapFileSummary& s, const std::optional<WorldFigures>& world) {
  nlohmann::json submaps = nlohmann::json::array();
  for (const SubmapSummary& sm : s.submaps) {
    const Pose& T = sm.info.T_world_submap;
    const Eigen::Matrix4d m = T.matrix();
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
    const Eigen::Vector3d t = T.translation(), rpy = rpy_degrees(T);
    submaps.push_back({{"id", sm.info.id},
                       {"T_world_submap", rows},
                       {"translation", {t.x(), t.y(), t.z()}},
                       {"rpy_deg", {rpy.x(), rpy.y(), rpy.z()}},
                       {"time_range", time_range_json(sm.info.time_range)},
                       {"path_length", sm.info.path_length},
                       {"blocks", sm.blocks},
                       {"known_voxels", sm.known_voxels},
                       {"occupied_voxels", sm.occupied_voxels},
                       {"semantic_voxels", sm.semantic_voxels}});
  }
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
          {"submaps", submaps}};
  if (world)
    j["check"] = {{"ok", true},
                  {"index_cells", world->index_cells},
                  {"index_cells_in_several_submaps", world->index_cells_shared},
                  {"occupied_world_cells", world->occupied_world_cells}};
  return j;
}

std::string megabytes(uint64_t bytes) { return fmt::format("{:.1f} MB", static_cast<double>(bytes) / 1e6); }

void print_text(const std::string& path, const MapFileSummary& s, const std::optional<WorldFigures>& world) {
  fmt::print("map        {} (format version {})\n", path, s.format_version);
  fmt::print("voxels     {} known, {} occupied (voxel size {} m)\n", s.known_voxels, s.occupied_voxels,
             s.params.occupancy.voxel_size);
  fmt::print("semantics  {} semantic voxels, {}-d {} embeddings\n", s.semantic_voxels, s.params.semantic.dim,
             to_string(s.params.semantic.precision));
  // Text from the map file, printed with control characters escaped (core/text_escape.hpp).
  fmt::print("model      {}\n", s.info.model_id.empty() ? "(none)" : escape_control(s.info.model_id));
  fmt::print("ontology   {}\n", escape_control(s.info.ontology));
  fmt::print("source     {}\n", s.info.source.empty() ? "(not recorded)" : escape_control(s.info.source));
  if (!s.info.config.empty()) {
    fmt::print("made with  ");
    bool first = true;
    std::size_t start = 0;
    while (start < s.info.config.size()) {  // the recorded options, one per line
      const std::size_t end = std::min(s.info.config.find('\n', start), s.info.config.size());
      fmt::print("{}{}\n", first ? "" : "           ", escape_control(s.info.config.substr(start, end - start)));
      first = false;
      start = end + 1;
    }
  }
  fmt::print("bytes      file {}, in memory {}\n", megabytes(s.file_bytes),
             s.memory_bytes ? megabytes(s.memory_bytes) + " (when saved)" : "not recorded (submaps left memory while mapping)");
  fmt::print("           on disk: occupancy {}, semantics {}", megabytes(s.occupancy_payload_bytes),
             megabytes(s.semantic_payload_bytes));
  if (s.semantic_voxels)
    fmt::print(" = {:.0f} B per semantic voxel (whole file: {:.0f} B)", per_voxel(s.semantic_payload_bytes, s.semantic_voxels),
               per_voxel(s.file_bytes, s.semantic_voxels));
  fmt::print("\nsubmaps    {} (a new one every {} of path)\n", s.submaps.size(),
             s.params.submap_length > 0 ? fmt::format("{:g} m", s.params.submap_length) : std::string("... never"));
  for (const SubmapSummary& sm : s.submaps) {
    const Pose& T = sm.info.T_world_submap;
    const Eigen::Vector3d t = T.translation(), rpy = rpy_degrees(T);
    const TimeRange& tr = sm.info.time_range;
    fmt::print("  id {:<4} t = ({:.2f}, {:.2f}, {:.2f}) m  rpy = ({:.1f}, {:.1f}, {:.1f}) deg  time {}  path {:.1f} m  "
               "{} known, {} occupied, {} semantic voxels\n",
               sm.info.id, t.x(), t.y(), t.z(), rpy.x(), rpy.y(), rpy.z(),
               tr.empty() ? std::string("(none)") : fmt::format("{:.3f}..{:.3f} s", tr.begin, tr.end),
               sm.info.path_length, sm.known_voxels, sm.occupied_voxels, sm.semantic_voxels);
  }
  if (world)
    fmt::print("check      OK: every row loads and holds possible values; global index {} cells ({} shared by several "
               "submaps), {} occupied world cells\n",
               world->index_cells, world->index_cells_shared, world->occupied_world_cells);
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand("info", "Show what a map file holds: voxel counts, sizes, submaps and poses, "
                                          "voxel size, embedding dimension and precision, model, ontology, source");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required();
  cmd->add_flag("--json", opt->json, "Print JSON instead of text");
  cmd->add_flag("--check", opt->check,
                "Load every row and validate it (checksums and meaning: finite values, rigid poses, unique keys, "
                "keys in range), then read the map through the global index");
  cmd->callback([opt] {
    const MapFileSummary s = read_map_summary(opt->map);
    std::optional<WorldFigures> world;
    if (opt->check) world = read_world(opt->map);
    if (opt->json) fmt::print("{}\n", to_json(opt->map, s, world).dump(2, ' ', true, nlohmann::json::error_handler_t::replace));
    else print_text(opt->map, s, world);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_info
