// `slamvdb inspect`: what an input holds before mapping it: a recording's containers, time span,
// topics, tf frames and which topics map / slam / odometry would use (and why), or a dataset
// folder's scans, images, poses and camera.
#include <fmt/format.h>

#include <memory>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/sensors/input_summary.hpp"

namespace slamvdb::cli::cmd_inspect {
namespace {

struct Options {
  std::string input;
  bool json = false;
};

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "inspect",
      "What an input holds: a recording's (ROS 1 bag, ROS 2 bag, MCAP) containers, duration, start and end, per topic "
      "the type, count, rate and size, the tf frames, and which topics map, slam and odometry would use for the LiDAR, "
      "camera, camera info, SIMULATED labels and poses (and why); a dataset folder's scans, images, poses and camera.");
  cmd->add_option("input", opt->input, "Recording (.bag, .mcap, ROS 2 bag folder or .db3) or dataset folder")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_flag("--json", opt->json, "Print JSON instead of text");
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("input", opt->input);
  cmd->callback([opt, io] {
    io->check();
    const InputSummary summary = summarize_input(opt->input);
    fmt::print("{}", opt->json ? summary_json(summary) : escape_control_keep_lines(summary_text(summary)));
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_inspect
