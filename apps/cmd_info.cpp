// `slamvdb info`: what a map file holds (counts, sizes, submaps, parameters, model), read from its
// metadata without loading the voxels; with --check, loaded and validated in full and read through
// the global index (world frame).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>

#include "command_registry.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/map_info_json.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_info {
namespace {

struct Options {
  std::string map;
  bool json = false;
  bool check = false;
};

// The figures of a full load (info --check), through the same library function as GET /api/info.
MapWorldFigures read_world(const std::string& path) { return map_world_figures(load_map(path)); }

std::string megabytes(uint64_t bytes) { return fmt::format("{:.1f} MB", static_cast<double>(bytes) / 1e6); }

void print_text(const std::string& path, const MapFileSummary& s, const std::optional<MapWorldFigures>& world) {
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
    fmt::print(" = {:.0f} B per semantic voxel (whole file: {:.0f} B)", bytes_per_voxel(s.semantic_payload_bytes, s.semantic_voxels),
               bytes_per_voxel(s.file_bytes, s.semantic_voxels));
  const std::map<int, std::size_t> counts = submaps_per_session(s);
  fmt::print("\nsessions   {}\n", s.info.sessions.size());
  for (const SessionInfo& session : s.info.sessions) {
    const TimeRange& tr = session.time;
    fmt::print("  id {:<4} {}  source {}{}  time {}  {} submaps\n", session.id, escape_control(session.name),
               session.source.empty() ? "(not recorded)" : escape_control(session.source),
               session.robot.empty() ? std::string() : "  robot " + escape_control(session.robot),
               tr.empty() ? std::string("(none)") : fmt::format("{:.3f}..{:.3f} s", tr.begin, tr.end),
               counts.at(session.id));
  }
  fmt::print("submaps    {} (a new one every {} of path)\n", s.submaps.size(),
             s.params.submap_length > 0 ? fmt::format("{:g} m", s.params.submap_length) : std::string("... never"));
  for (const SubmapSummary& sm : s.submaps) {
    const Pose& T = sm.info.T_world_submap;
    const Eigen::Vector3d t = T.translation(), rpy = rpy_degrees(T);
    const TimeRange& tr = sm.info.time_range;
    fmt::print("  id {:<4} session {}  t = ({:.2f}, {:.2f}, {:.2f}) m  rpy = ({:.1f}, {:.1f}, {:.1f}) deg  time {}  path {:.1f} m  "
               "{} known, {} occupied, {} semantic voxels\n",
               sm.info.id, sm.info.session, t.x(), t.y(), t.z(), rpy.x(), rpy.y(), rpy.z(),
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
  auto* cmd = root.add_subcommand("info", "Show what a map file holds: voxel counts, sizes, sessions, submaps and poses, "
                                          "voxel size, embedding dimension and precision, model, ontology, source");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required();
  cmd->add_flag("--json", opt->json, "Print JSON instead of text");
  cmd->add_flag("--check", opt->check,
                "Load every row and validate it (checksums and meaning: finite values, rigid poses, unique keys, "
                "keys in range), then read the map through the global index");
  cmd->callback([opt] {
    const MapFileSummary s = read_map_summary(opt->map);
    std::optional<MapWorldFigures> world;
    if (opt->check) world = read_world(opt->map);
    if (opt->json) fmt::print("{}\n", map_info_json(opt->map, s, world).dump(2, ' ', true, nlohmann::json::error_handler_t::replace));
    else print_text(opt->map, s, world);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_info
