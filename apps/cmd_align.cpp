// `slamvdb align BASE OTHER -o OTHER_in_BASE`: where another session's map lies in a base map's
// world, from the two maps alone (sessions/map_alignment.hpp), and the other map written with its
// submap anchors moved there (no re-integration). A refusal (no overlap, ambiguous evidence,
// incompatible maps) exits 1 with the reason and writes no map.
#include <fmt/format.h>

#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/alignment_report.hpp"
#include "slamvdb/sessions/map_alignment.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_align {
namespace {

struct Options {
  std::string base, other, output, json, initial;
  std::string adjusted_base;  // --adjust-base: BASE with its anchors corrected too, written here
  double initial_radius = 10.0;
  std::optional<Pose> prior;  // from --initial, once checked
};

// "x,y,z,yaw" (metres, degrees): four finite numbers, nothing else.
Pose parse_initial_pose(const std::string& text) {
  std::istringstream in(text);
  std::array<double, 4> v{};
  std::string token;
  for (double& x : v) {
    if (!std::getline(in, token, ',') || !CLI::detail::lexical_cast(token, x) || !std::isfinite(x))
      usage_error(fmt::format("--initial '{}' needs four finite numbers x,y,z,yaw (metres, degrees)", text));
  }
  if (std::getline(in, token, ','))
    usage_error(fmt::format("--initial '{}' has more than four numbers (x,y,z,yaw)", text));
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(v[3] * M_PI / 180.0, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(v[0], v[1], v[2]);
  return T;
}

void run(const Options& opt) {
  // Before loading the voxels: maps that cannot share a world are refused from their metadata.
  const MapFileSummary base_summary = read_map_summary(opt.base), other_summary = read_map_summary(opt.other);
  const std::string incompatible =
      sessions::map_incompatibility(base_summary.params, base_summary.info, other_summary.params, other_summary.info);
  if (!incompatible.empty()) throw Error(fmt::format("cannot align {} to {}: {}", opt.other, opt.base, incompatible));
  SemanticMap base = load_map(opt.base);
  SemanticMap other = load_map(opt.other);
  sessions::AlignmentConfig config;
  if (opt.prior) config.prior = sessions::AlignmentPrior{*opt.prior, opt.initial_radius, 0.52};
  const sessions::MapAlignment result = opt.adjusted_base.empty()
                                            ? sessions::align_maps(base, other, config)
                                            : sessions::align_maps_adjusting_base(base, other, config);
  fmt::print("align {} ({} submaps) to {} ({} submaps)\n{}", opt.other, other_summary.submaps.size(), opt.base,
             base_summary.submaps.size(), alignment_report_text(result));
  if (!opt.json.empty()) write_output_file(opt.json, alignment_report_json(result).dump(2) + "\n");
  if (!result.alignment.aligned)
    throw Error(fmt::format("cannot align {} to {}: {} ({} not written)", opt.other, opt.base, result.alignment.refused,
                            opt.output));
  const MapFileSummary written = save_map(opt.output, other);
  fmt::print("wrote {} ({} submaps, {:.1f} MB)\n", opt.output, written.submaps.size(),
             static_cast<double>(written.file_bytes) / 1e6);
  if (!opt.adjusted_base.empty()) {
    const MapFileSummary adjusted = save_map(opt.adjusted_base, base);
    fmt::print("wrote {} (BASE with adjusted anchors, {} submaps, {:.1f} MB)\n", opt.adjusted_base,
               adjusted.submaps.size(), static_cast<double>(adjusted.file_bytes) / 1e6);
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "align",
      "Find where OTHER lies in BASE's world from the two maps alone (places with ScanContext descriptors, "
      "candidate pairs verified by ICP, the largest consistent set, a last point-to-plane refinement), then write "
      "OTHER with its submap anchors moved into BASE's world and corrected by a joint pose graph (no "
      "re-integration). Refuses (exit 1, with the reason; no map written) maps that do not overlap, ambiguous "
      "evidence (look-alike places), and maps with different voxel sizes, embedding models or ontologies.");
  cmd->add_option("base", opt->base, "The map whose world frame is kept (.svdb)")->required()->check(CLI::ExistingFile);
  cmd->add_option("other", opt->other, "The map to align (.svdb)")->required()->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", opt->output, "OTHER in BASE's world: the map file to write (.svdb)")->required();
  cmd->add_option("--json", opt->json,
                  "Write the report as JSON: the transform (x y z, roll pitch yaw, matrix), every verified pair, "
                  "the consistent set, the uncertainty, the refined overlap and RMSE, the corrected anchors");
  cmd->add_option("--initial", opt->initial,
                  "A prior for OTHER's world in BASE's (e.g. from GNSS): x,y,z,yaw in metres and degrees "
                  "(write --initial=-3,2,0,90 when it starts with a minus); it narrows the search, the evidence "
                  "rules stay");
  cmd->add_option("--initial-radius", opt->initial_radius,
                  "With --initial: how far (metres) a place may lie from where the prior puts it (unused without)")
      ->check(finite_range(0.0, bounds::kMaxRange, true))
      ->capture_default_str();
  cmd->add_option("--adjust-base", opt->adjusted_base,
                  "Correct BASE's submap anchors too (one joint pose graph over both maps' submaps, BASE's first "
                  "submap held; no re-integration) and write BASE so adjusted to this file (.svdb). Default: BASE "
                  "stays as it is");
  add_option_checks(cmd, [opt] {
    if (!opt->initial.empty()) opt->prior = parse_initial_pose(opt->initial);
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("base", opt->base);
  io->input("other", opt->other);
  io->output("-o", opt->output);
  io->output("--json", opt->json);
  io->output("--adjust-base", opt->adjusted_base);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_align
