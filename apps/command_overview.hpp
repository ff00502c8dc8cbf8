#pragma once
// `slamvdb --help`: the commands in the order of the work (make data, map, localize, ask, look,
// share, evaluate, tools), one line each. Each command's own --help keeps its full description; the
// lines here are the overview only. A command missing from the table is listed last under
// "Other" (CliConventions.TopLevelHelpListsTheWorkflowOneLineEach fails on it).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

namespace slamvdb::cli {

struct CommandOverviewLine {
  const char* group;
  const char* name;
  const char* line;
};

inline const std::vector<CommandOverviewLine>& command_overview() {
  static const std::vector<CommandOverviewLine> table = {
      {"Make data", "synth", "Write a SIMULATED sequence in the RELLIS-3D layout"},
      {"Make data", "convert", "Write a dataset folder as a ROS 2 MCAP recording"},
      {"Make data", "demo", "The whole job on a SIMULATED drive, with pictures"},
      {"Map", "map", "Map a dataset on its poses into a map file (.svdb)"},
      {"Map", "slam", "Map a dataset on its own odometry and loop closure"},
      {"Map", "align", "Put another session's map into a map's world (maps alone)"},
      {"Map", "merge", "Merge aligned maps of several sessions into one map file"},
      {"Localize", "odometry", "LiDAR odometry (and loop closure): a pose per scan"},
      {"Ask", "query", "Voxels most like a text, class or vector; what is at a point"},
      {"Ask", "classify", "Label every semantic voxel with a terrain class"},
      {"Ask", "train-queries", "Train one query vector per class on labelled images"},
      {"Ask", "import-queries", "Make a query set from a folder of CLASS.csv vectors"},
      {"Ask", "serve", "Serve a map over HTTP: a JSON API for planners and scripts"},
      {"Look", "inspect", "What a recording or dataset holds, and which topics map uses"},
      {"Look", "info", "What a map file holds and how it was made"},
      {"Look", "export", "Write a map as .ply, .pcd, .png, .csv, .npy or .html"},
      {"Share", "push", "Push a map's submaps into a fleet map (PostgreSQL + PostGIS)"},
      {"Share", "pull", "Write a region of a fleet map as a map file"},
      {"Share", "add-shard", "Add a PostgreSQL server to a fleet map (postgres_fdw)"},
      {"Evaluate", "eval", "Score a map against a labelled sequence (Table 6.1)"},
      {"Evaluate", "eval-images", "Score the per-image baseline against the 2D labels"},
      {"Evaluate", "eval-trajectory", "Score a trajectory against ground truth (ATE, RPE)"},
      {"Tools", "tokenize", "Print the CLIP token ids of a text"},
      {"Tools", "embed-text", "Embed a text with a CLIP-style text encoder"},
      {"Tools", "segment", "Segment one image by class names with a dense encoder"},
  };
  return table;
}

// The root's command list in workflow order with group headings; everything else as CLI11 does it.
class CommandOverviewFormatter : public CLI::Formatter {
  static constexpr std::size_t kNameWidth = 19;  // "  eval-trajectory" and a space: lines fit 80 columns

 public:
  std::string make_subcommands(const CLI::App* app, CLI::AppFormatMode mode) const override {
    if (app->get_parent() != nullptr) return CLI::Formatter::make_subcommands(app, mode);
    std::vector<const CLI::App*> rest = app->get_subcommands({});
    std::ostringstream out;
    std::string group;
    const auto put = [&](const std::string& heading, const CLI::App* sub, const char* line) {
      if (heading != group) out << "\n" << (group = heading) << ":\n";
      if (mode == CLI::AppFormatMode::All) out << sub->help(sub->get_name(), CLI::AppFormatMode::Sub) << "\n";
      else CLI::detail::format_help(out, sub->get_name(), line, kNameWidth);
    };
    for (const CommandOverviewLine& c : command_overview()) {
      const auto it = std::find_if(rest.begin(), rest.end(), [&](const CLI::App* s) { return s->get_name() == c.name; });
      if (it == rest.end()) continue;
      put(c.group, *it, c.line);
      rest.erase(it);
    }
    for (const CLI::App* sub : rest) put("Other", sub, sub->get_description().c_str());
    out << "\nslamvdb COMMAND --help describes a command in full.\n";
    return out.str();
  }
};

}  // namespace slamvdb::cli
