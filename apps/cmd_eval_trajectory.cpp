// `slamvdb eval-trajectory`: accuracy of an estimated trajectory against ground truth: ATE after
// SE(3) Umeyama alignment, RPE between consecutive poses, KITTI-style drift, and a PNG plot.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "command_registry.hpp"
#include "option_checks.hpp"
#include "io_options.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/trajectory_io.hpp"
#include "slamvdb/io/trajectory_plot.hpp"
#include "slamvdb/localization/trajectory_metrics.hpp"

namespace slamvdb::cli::cmd_eval_trajectory {
namespace {

using namespace slamvdb::localization;

struct Options {
  std::string estimate, truth, png, json, loops;
  double max_dt = 0.02;
};

void run(const Options& opt) {
  const StampedPoses est = read_trajectory(opt.estimate);
  const StampedPoses gt = read_trajectory(opt.truth);
  std::vector<Pose> e, g;
  std::vector<double> stamps;
  std::string pairing;
  if (est.format == PoseFormat::kTum && gt.format == PoseFormat::kTum) {
    for (const auto& [i, j] : associate_by_stamp(est.stamps, gt.stamps, opt.max_dt)) {
      e.push_back(est.poses[i]);
      g.push_back(gt.poses[j]);
      stamps.push_back(est.stamps[i]);
    }
    pairing = fmt::format("by stamp (within {} s)", opt.max_dt);
  } else {
    if (est.poses.size() != gt.poses.size())
      throw Error(fmt::format("{} has {} poses but {} has {}; without stamps on both sides (TUM) poses pair by index",
                              opt.estimate, est.poses.size(), opt.truth, gt.poses.size()));
    e = est.poses;
    g = gt.poses;
    stamps = est.stamps;
    pairing = "by index";
  }
  if (e.size() < 3) throw Error(fmt::format("only {} pose pairs {}; need at least 3", e.size(), pairing));
  const AteResult ate = absolute_trajectory_error(e, g);
  const RpeResult rpe = relative_pose_error(e, g);
  const DriftResult drift = kitti_drift(e, g);
  const double length = path_length(g);
  fmt::print("{} vs {}: {} pose pairs {}, ground-truth path {:.1f} m\n", opt.estimate, opt.truth, e.size(), pairing, length);
  fmt::print("  ATE  rmse {:.3f} m, mean {:.3f} m, median {:.3f} m, max {:.3f} m (after SE(3) alignment)\n", ate.rmse,
             ate.mean, ate.median, ate.max);
  fmt::print("  RPE  {:.4f} m, {:.4f} deg per step (rmse)\n", rpe.translation_rmse, rpe.rotation_rmse_deg);
  fmt::print("  drift {:.3f} %, {:.5f} deg/m over {} segments of {:.1f} m\n", drift.translation_percent,
             drift.rotation_deg_per_m, drift.segments, fmt::join(drift.lengths, ", "));

  std::vector<std::pair<Vec3d, Vec3d>> edges;
  if (!opt.loops.empty()) {
    std::ifstream in(opt.loops);
    nlohmann::json j;
    try {
      in >> j;
    } catch (const std::exception& ex) {
      throw Error(fmt::format("cannot read loops from {}: {}", opt.loops, ex.what()));
    }
    const auto position_at = [&](double t) {
      const auto it = std::lower_bound(stamps.begin(), stamps.end(), t - 1e-6);
      const std::size_t i = std::min<std::size_t>(it - stamps.begin(), stamps.size() - 1);
      return ate.T_truth_estimate * e[i].translation();
    };
    for (const auto& loop : j.value("loops", nlohmann::json::array()))
      edges.emplace_back(position_at(loop.at("candidate_stamp").get<double>()),
                         position_at(loop.at("query_stamp").get<double>()));
  }
  if (!opt.png.empty()) {
    PlotLine truth{"ground truth", {}, {40, 40, 40}}, estimate{"estimate (aligned)", {}, {220, 40, 40}};
    for (std::size_t i = 0; i < e.size(); ++i) {
      truth.positions.push_back(g[i].translation());
      estimate.positions.push_back(ate.T_truth_estimate * e[i].translation());
    }
    write_trajectory_plot(opt.png, {truth, estimate}, edges);
    fmt::print("  plot written to {}\n", opt.png);
  }
  if (!opt.json.empty()) {
    const nlohmann::json j = {
        {"pairs", e.size()}, {"pairing", pairing}, {"path_length_m", length},
        {"ate", {{"rmse", ate.rmse}, {"mean", ate.mean}, {"median", ate.median}, {"max", ate.max}}},
        {"rpe", {{"translation_rmse_m", rpe.translation_rmse}, {"rotation_rmse_deg", rpe.rotation_rmse_deg}}},
        {"drift", {{"translation_percent", drift.translation_percent}, {"rotation_deg_per_m", drift.rotation_deg_per_m},
                   {"segments", drift.segments}, {"segment_lengths_m", drift.lengths}}}};
    write_output_file(opt.json, j.dump(2) + "\n");
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "eval-trajectory",
      "Compare an estimated trajectory with ground truth (KITTI or TUM files, detected): ATE after SE(3) Umeyama "
      "alignment, RPE, KITTI-style drift (segments of 100..800 m, or 10..50% of a path shorter than 200 m).");
  cmd->add_option("estimate", opt->estimate, "Estimated poses")->required()->check(CLI::ExistingFile);
  cmd->add_option("truth", opt->truth, "Ground-truth poses")->required()->check(CLI::ExistingFile);
  cmd->add_option("--png", opt->png, "Write a plot seen from above");
  cmd->add_option("-o,--output,--json", opt->json, "Write the metrics as JSON");
  cmd->add_option("--loops", opt->loops, "JSON summary of `slamvdb odometry --json` whose loops the plot draws")
      ->check(CLI::ExistingFile);
  cmd->add_option("--max-dt", opt->max_dt, "Largest stamp difference when pairing TUM files (s)")
      ->check(finite_range(0, 1e6, true))->capture_default_str();
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("estimate", opt->estimate);
  io->input("truth", opt->truth);
  io->input("--loops", opt->loops);
  io->output("--png", opt->png);
  io->output("-o", opt->json);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_eval_trajectory
