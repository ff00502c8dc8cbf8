// `slamvdb merge A B [...] -o SITE`: maps of different sessions that share one world (`align`)
// as one map file holding every session's submaps, each still in its session, submaps of
// different sessions over the same place merged into one (sessions/map_merge.hpp). Inputs that cannot share a world are refused from their metadata,
// naming the difference, before any voxel is loaded; the output is written whole or not at all.
#include <fmt/format.h>

#include <memory>
#include <string>
#include <nlohmann/json.hpp>
#include <vector>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "yaml_config.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/sessions/map_merge.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_merge {
namespace {

struct Options {
  std::vector<std::string> maps;
  std::string output, json;
  sessions::OverlapMergeOptions overlap;
  bool keep_apart = false;
};

nlohmann::json merge_contents_json(const sessions::MapContents& c) {
  return {{"sessions", c.sessions},
          {"submaps", c.submaps},
          {"occupied_voxels", c.occupied_voxels},
          {"semantic_voxels", c.semantic_voxels},
          {"observations", c.observations}};
}

void run(const Options& opt, const std::string& config) {
  std::vector<MapFileSummary> summaries;
  for (const std::string& path : opt.maps) summaries.push_back(read_map_summary(path));
  for (std::size_t i = 1; i < summaries.size(); ++i) {
    const std::string incompatible = sessions::merge_incompatibility(summaries[0].params, summaries[0].info,
                                                                     summaries[i].params, summaries[i].info);
    if (!incompatible.empty())
      throw Error(fmt::format("cannot merge {} with {}: {} ({} not written)", opt.maps[i], opt.maps[0], incompatible,
                              opt.output));
  }
  std::vector<SemanticMap> inputs;
  for (const std::string& path : opt.maps) inputs.push_back(load_map(path));
  sessions::MapMergeReport report;
  SemanticMap merged = [&] {
    try {
      return sessions::merge_session_maps(inputs, opt.maps, report, opt.overlap);  // checks that no count is lost
    } catch (const Error& e) {
      throw Error(fmt::format("{}: {} not written", e.what(), opt.output));
    }
  }();
  MapInfo info = merged.info();
  info.source = fmt::format("merge of {} maps: {}", opt.maps.size(), fmt::join(opt.maps, ", "));
  info.config = config;  // how this file was made: the merge (each input file keeps its own)
  merged.set_info(info);
  const sessions::MapContents& m = report.merged;
  const MapFileSummary written = save_map(opt.output, merged);
  for (std::size_t i = 0; i < opt.maps.size(); ++i)
    fmt::print("input      {}: {} sessions, {} submaps, {} semantic voxels, {} observations\n", opt.maps[i],
               report.inputs[i].sessions, report.inputs[i].submaps, report.inputs[i].semantic_voxels,
               report.inputs[i].observations);
  uint64_t dropped = 0;
  for (const sessions::SubmapAbsorption& a : report.absorbed) {
    fmt::print("overlap    submap {} (session {}) merged into submap {} (session {}): {:.1f}% overlap, {} observations\n",
               a.source_id, a.source_session, a.target_id, a.target_session, 100 * a.overlap, a.observations_moved);
    dropped += a.observations_dropped_free + a.observations_clipped;
  }
  fmt::print("merged     {} sessions, {} submaps, {} occupied and {} semantic voxels, {} observations ({})\n",
             m.sessions, m.submaps, m.occupied_voxels, m.semantic_voxels, m.observations,
             dropped == 0 ? std::string("none lost")
                          : fmt::format("{} dropped where merged voxels became free or counts saturated", dropped));
  fmt::print("wrote {} ({:.1f} MB)\n", opt.output, static_cast<double>(written.file_bytes) / 1e6);
  if (!opt.json.empty()) {
    nlohmann::json j = {{"output", opt.output}, {"merged", merge_contents_json(m)}, {"inputs", nlohmann::json::array()}};
    for (std::size_t i = 0; i < opt.maps.size(); ++i) {
      nlohmann::json input = merge_contents_json(report.inputs[i]);
      input["path"] = opt.maps[i];
      j["inputs"].push_back(input);
    }
    j["overlap_merges"] = nlohmann::json::array();
    for (const sessions::SubmapAbsorption& a : report.absorbed)
      j["overlap_merges"].push_back({{"target_submap", a.target_id},
                                     {"source_submap", a.source_id},
                                     {"target_session", a.target_session},
                                     {"source_session", a.source_session},
                                     {"overlap", a.overlap},
                                     {"observations", a.observations_moved},
                                     {"observations_dropped_free", a.observations_dropped_free},
                                     {"observations_clipped", a.observations_clipped}});
    write_output_file(opt.json, j.dump(2) + "\n");
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "merge",
      "Merge maps of different sessions that share one world (made so by `slamvdb align`) into one map file: every "
      "input's submaps, each in the session it was mapped in (`info` lists them). A submap whose occupied voxels "
      "overlap those of an earlier input's submap of another session enough (--min-overlap) is merged into it as the "
      "loop closer merges (counts add, embeddings by count-weighted mean, every voxel once); the merged submap stays "
      "in the earlier session. Refuses (exit 1, "
      "naming the difference; nothing written) maps with different voxel sizes, embedding models, embedding "
      "dimensions, ontologies or occupancy settings.");
  cmd->add_option("maps", opt->maps, "The maps to merge (.svdb), two or more")
      ->required()
      ->expected(2, -1)
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", opt->output, "The merged map file to write (.svdb)")->required();
  cmd->add_option("--json", opt->json, "Write what each input held and what the merged map holds as JSON");
  cmd->add_option("--min-overlap", opt->overlap.min_overlap,
                  "Merge two submaps of different sessions when this fraction of the smaller one's occupied voxels "
                  "lands on the other's")
      ->check(finite_range(0, 1, true))
      ->capture_default_str();
  cmd->add_flag("--keep-sessions-apart", opt->keep_apart,
                "Merge no submaps: each stays in its own session (for --session on export, query, classify)");
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("maps", opt->maps);
  io->output("-o", opt->output);
  io->output("--json", opt->json);
  cmd->callback([opt, io, cmd] {
    io->check();
    opt->overlap.enabled = !opt->keep_apart;
    run(*opt, effective_config(*cmd));
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_merge
