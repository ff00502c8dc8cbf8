// `slamvdb convert`: a dataset folder (RELLIS-3D or KITTI layout, e.g. what `slamvdb synth` writes)
// as a ROS 2 MCAP recording (sensors/mcap_export.hpp: PointCloud2, CompressedImage, CameraInfo,
// label images, /tf_static, ground-truth Odometry), to open in Foxglove or RViz or to feed any
// command that reads recordings.
#include <fmt/format.h>

#include <memory>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "mcap_output.hpp"
#include "slamvdb/recording/recording.hpp"

namespace slamvdb::cli::cmd_convert {
namespace {

struct Options {
  std::string input, output;
  McapOutputOptions mcap;
};

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "convert",
      "Write a dataset folder (RELLIS-3D or KITTI layout, e.g. from `slamvdb synth`) as a ROS 2 MCAP recording: "
      "PointCloud2, CompressedImage, CameraInfo, label images, /tf_static and ground-truth Odometry, in the topics "
      "of RELLIS-3D's bags. Open it in Foxglove, or give it to map, slam, odometry or inspect.");
  cmd->add_option("input", opt->input, "Dataset folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", opt->output, "MCAP file to write (replaced if it exists)")->required();
  add_mcap_output_options(cmd, opt->mcap);
  add_option_checks(cmd, [opt] {
    if (recording::is_recording(opt->input))
      usage_error(fmt::format("{} is a recording already; convert reads dataset folders", opt->input));
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("input", opt->input);
  io->output("-o", opt->output, {}, /*lock=*/true);
  cmd->callback([opt, io] {
    io->check();
    write_folder_as_mcap(opt->input, opt->output, opt->mcap, "sequence " + opt->input);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_convert
