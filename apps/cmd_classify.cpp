// `slamvdb classify`: every semantic voxel of a map labelled with the class of the most similar
// query vector (the paper's terrain classes; void -> second-best), read through the global index.
#include <fmt/format.h>

#include <chrono>
#include <fstream>

#include "command_registry.hpp"
#include "demo_outputs.hpp"
#include "feature_options.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli {
namespace {

struct Options {
  std::string map, queries, csv;
  bool no_void_rule = false, ignore_model_id = false;
};

void run(const Options& opt) {
  if (!opt.csv.empty()) check_output_file(opt.csv, "--output");
  const QuerySet queries = load_query_set(opt.queries);
  const auto t0 = std::chrono::steady_clock::now();
  const SemanticMap map = load_map(opt.map);
  ClassifyOptions options;
  options.void_to_second_best = !opt.no_void_rule;
  std::vector<ClassifiedCell> cells =
      classify_map(map, queries, options, opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch);
  sort_by_cell(cells);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::vector<std::size_t> per_class(static_cast<std::size_t>(queries.size()), 0);
  std::size_t unclassified = 0;
  for (const ClassifiedCell& c : cells) {
    if (c.match.class_index == kNoClass) ++unclassified;
    else ++per_class[static_cast<std::size_t>(c.match.class_index)];
  }
  fmt::print("{}: {} semantic voxels classified with {} ({} classes, void -> second best {}) in {:.2f} s\n", opt.map,
             cells.size(), opt.queries, queries.size(), opt.no_void_rule ? "off" : "on", seconds);
  fmt::print("| class | voxels | share |\n|---|---|---|\n");
  for (int k = 0; k < queries.size(); ++k)
    fmt::print("| {} | {} | {:.1f}% |\n", queries.names[k], per_class[k],
               cells.empty() ? 0.0 : 100.0 * per_class[k] / cells.size());
  if (unclassified) fmt::print("| (no class: zero embedding) | {} | |\n", unclassified);
  if (!opt.csv.empty()) {
    write_classified_csv(opt.csv, cells, queries);
    fmt::print("CSV  {}: {} rows\n", opt.csv, cells.size());
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "classify",
      "Label every semantic voxel of a map with the class of its most similar query vector (cosine; a voxel whose "
      "best class is void takes its second-best, as in the paper), read through the global index in the world frame");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--queries", opt->queries, "Query set file (train-queries / import-queries)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", opt->csv, "Write one row per voxel: x,y,z,class,score,margin,count (CSV)");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "Let void classes win (the paper's rule is on by default)");
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "Accept queries whose model id differs from the map's (the dimension is still checked)");
  cmd->callback([opt] { run(*opt); });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli
