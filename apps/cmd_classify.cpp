// `slamvdb classify`: every semantic voxel of a map labelled with the class of the most similar
// query vector (the paper's terrain classes; void -> second-best), read through the global index.
#include <fmt/format.h>

#include <chrono>
#include <fstream>

#include "command_registry.hpp"
#include "demo_outputs.hpp"
#include "feature_options.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "map_source_options.hpp"
#include "region_options.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/nav_grid_files.hpp"
#include "slamvdb/query/class_summary.hpp"
#include "slamvdb/query/nav_grid.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_classify {
namespace {

struct Options {
  std::string queries, csv, grid, png;
  bool no_void_rule = false, ignore_model_id = false;
  double robot_height = NavGridOptions{}.robot_height;
  double grid_resolution = 0;
  float min_confidence = 0.f;
  std::vector<std::string> costs;  // NAME=COST
  RegionOptions region;
  MapSourceOptions source;
};

// Cost per class of the query set (query/nav_grid.hpp's rules): a bad --cost or a class without a
// cost is a usage error (a planner must not guess).
std::vector<int8_t> class_costs(const QuerySet& queries, const std::vector<std::string>& overrides) {
  try {
    return nav_class_costs(queries.names, overrides);
  } catch (const Error& e) {
    usage_error(fmt::format("--cost: {}", e.what()));
  }
}

// The files of --grid PREFIX.
std::vector<std::filesystem::path> nav_grid_files_of(const std::string& prefix) {
  const NavGridFiles files = nav_grid_files(prefix);
  return {files.pgm, files.yaml, files.png};
}

void run(const Options& opt) {
  const QuerySet queries = load_query_set(opt.queries);
  const auto t0 = std::chrono::steady_clock::now();
  ClassifyOptions options;
  options.void_to_second_best = !opt.no_void_rule;
  const ModelIdCheck model_check = opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch;
  const std::optional<QueryRegion> region = opt.region.region();
  // A fleet region is classified tile by tile (bounded memory); the picture and the grid draw the
  // region's occupied voxels, so they read it whole, as a map file is.
  const bool by_tiles = !opt.source.db.empty() && opt.png.empty() && opt.grid.empty();
  std::optional<SemanticMap> map;
  if (!by_tiles) map.emplace(opt.source.read(region));
  std::vector<ClassifiedCell> cells = by_tiles ? opt.source.classify_fleet(*region, queries, options, model_check)
                                      : region ? classify_region(*map, queries, *region, options, model_check)
                                               : classify_map(*map, queries, options, model_check);
  sort_by_cell(cells);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const ClassSummary summary = summarize_classes(cells, queries, opt.min_confidence);
  fmt::print("{}: {} semantic voxels{} classified with {} ({} classes, void -> second best {}) in {:.2f} s\n", opt.source.name(),
             cells.size(), region ? " in the region (--bbox / --near)" : "", opt.queries, queries.size(),
             opt.no_void_rule ? "off" : "on", seconds);
  fmt::print("| class | voxels | share |\n|---|---|---|\n");
  for (int k = 0; k < queries.size(); ++k)
    fmt::print("| {} | {} | {:.1f}% |\n", markdown_cell(queries.names[k]), summary.per_class[k],
               summary.percent(summary.per_class[k]));
  if (opt.min_confidence > 0)
    fmt::print("| uncertain (confidence < {}) | {} | {:.1f}% |\n", opt.min_confidence, summary.uncertain,
               summary.percent(summary.uncertain));
  if (summary.unclassified) fmt::print("| (no class: zero embedding) | {} | |\n", summary.unclassified);
  if (summary.statistics_unknown)
    fmt::print("{} voxels have no observation statistics (a map file before format 3): their confidence is the class "
               "margin alone\n",
               summary.statistics_unknown);
  if (!opt.csv.empty()) {
    // A fleet region classified by tiles has no map here, and the fleet stores no per-voxel
    // session yet: its CSV has no last_session column (a map file's, pulled or not, has).
    write_classified_csv(opt.csv, cells, queries, opt.min_confidence, map ? &map->info().sessions : nullptr);
    fmt::print("CSV  {}: {} rows\n", opt.csv, cells.size());
  }
  const std::vector<Rgb> colours = class_colours(queries);
  if (!opt.png.empty()) {
    const BirdsEyeImage image = write_class_picture(opt.png, *map, cells, queries, submap_path(*map),
                                                    "path (submap anchors)", opt.min_confidence, region);
    fmt::print("PNG  {} (+ .yaml): {}x{} px at {:.3f} m per pixel, terrain layer by class\n", opt.png, image.rgb.cols,
               image.rgb.rows, image.resolution);
  }
  if (!opt.grid.empty()) {
    NavGridOptions options;
    options.robot_height = opt.robot_height;
    options.class_cost = class_costs(queries, opt.costs);
    options.min_confidence = opt.min_confidence;
    options.region = region;
    options.resolution = opt.grid_resolution;
    try {
      nav_grid_factor(opt.grid_resolution, map->params().index_cell());
    } catch (const Error& e) {
      throw Error(fmt::format("--grid-resolution: {}", e.what()));
    }  // cells are classify_region's for it (GET /api/nav-grid builds the same)
    const NavGrid grid = build_nav_grid(*map, cells, options);
    const NavGridFiles files =
        write_nav_grid(opt.grid, grid, queries.names, colours, submap_path(*map), opt.min_confidence);
    std::size_t lethal = 0, unknown = 0, uncertain_cells = 0;
    for (const int8_t c : grid.cost) lethal += c == kLethalCost, unknown += c == kUnknownCost;
    for (const uint8_t u : grid.uncertain) uncertain_cells += u;
    fmt::print("grid {} + {} + {}: {}x{} cells of {:.2f} m, {} lethal, {} unknown ({} of them uncertain ground) "
               "(robot height {} m)\n",
               files.pgm.string(), files.yaml.string(), files.png.string(), grid.width, grid.height, grid.resolution,
               lethal, unknown, uncertain_cells, opt.robot_height);
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "classify",
      "Label every semantic voxel of a map with the class of its most similar query vector (cosine; a voxel whose "
      "best class is void takes its second-best, as in the paper), read through the global index in the world frame");
  opt->source.add_to(cmd);
  cmd->add_option("--queries", opt->queries, "Query set file (train-queries / import-queries)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", opt->csv,
                  "Write one row per voxel: x,y,z,class,score,margin,count,confidence,last_session (CSV; class `uncertain` below "
                  "--min-confidence)");
  cmd->add_option("--png", opt->png,
                  "Write the terrain seen from above: the class of the ground of every column (not the top: tree "
                  "crowns do not hide it), with a legend, scale bar, north arrow, the submap path, and a map_server "
                  ".yaml beside it");
  cmd->add_option("--grid", opt->grid,
                  "Write a navigation grid PREFIX.pgm + PREFIX.yaml (ROS map_server / Nav2, mode raw: the pixel is the "
                  "cost, 0 free .. 100 lethal, 255 unknown) and PREFIX.png (classes, obstacles black, legend)");
  cmd->add_option("--robot-height", opt->robot_height,
                  "Grid: something occupied above the ground up to this height (m) is an obstacle")
      ->capture_default_str()
      ->check(finite_range(0.1, 100));
  cmd->add_option("--grid-resolution", opt->grid_resolution,
                  "Grid: metres per cell, a whole multiple of the map's index cell (each cell the worst of the index "
                  "cells it covers: lethal if one is, else the highest known cost). 0: the index cell")
      ->capture_default_str()
      ->check(finite_range(0, 1000));
  cmd->add_option("--cost", opt->costs,
                  "Grid: the cost of a class, CLASS=COST (-1 unknown .. 100 lethal; repeatable). Defaults: smooth 0, "
                  "rough 30, bumpy 60, obstacle 100, active 100, void unknown");
  cmd->add_option("--min-confidence", opt->min_confidence,
                  "Voxels whose confidence (0..1: the margin between the best and second-best class x n/(n+2) for n views; README 'Honest accuracy') is "
                  "below this are `uncertain`: so named in the CSV, hatched in --png and --grid's picture, unknown "
                  "(-1) in the grid. 0: off")
      ->capture_default_str()
      ->check(finite_range(0, 1));
  opt->region.add_to(cmd, "voxels classified and drawn (the table, -o, --png, --grid)");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "Let void classes win (the paper's rule is on by default)");
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "Accept queries whose model id differs from the map's (the dimension is still checked)");
  add_option_checks(cmd, [opt] {
    if (!opt->png.empty() && std::filesystem::path(opt->png).extension() != ".png")
      usage_error(fmt::format("--png {}: the picture is written as .png", opt->png));
    opt->region.region();
    opt->source.check(opt->region);
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("map", opt->source.map);
  io->input("--queries", opt->queries);
  io->output("-o", opt->csv);
  io->output("--png", opt->png, png_with_yaml);
  io->output("--grid", opt->grid, nav_grid_files_of);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_classify
