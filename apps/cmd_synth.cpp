// `slamvdb synth`: writes a SIMULATED off-road sequence (LiDAR scans, camera images, labels and
// ground-truth poses) in the RELLIS-3D layout, for tests and demos without the real dataset; with
// --format mcap also as a ROS 2 MCAP recording beside the files (OUT_DIR/drive.mcap).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <map>
#include <cstdio>
#include <memory>
#include <optional>
#include <regex>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "mcap_output.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/synth/sequence_writer.hpp"

namespace slamvdb::cli::cmd_synth {
namespace {

namespace fs = std::filesystem;

struct Options {
  std::string out;
  bool skip_space_check = false;
  synth::SynthConfig config;
  std::string image_size = "640x400";
  bool force = false;
  bool perfect_rig = false;
  int64_t noise_seed = 0;  // with --noise-seed only
  std::string format = "folder";
  McapOutputOptions mcap;
};

// Where --format mcap writes the recording.
constexpr const char* kSynthMcapName = "drive.mcap";

void parse_image_size(const std::string& text, synth::SynthConfig& config) {
  static const std::regex kSize(R"((\d{1,5})[xX](\d{1,5}))");
  std::smatch m;
  if (!std::regex_match(text, m, kSize))
    throw Error(fmt::format("--image-size '{}' is not WIDTHxHEIGHT (e.g. 640x400)", text));
  config.image_width = std::stoi(m[1]);
  config.image_height = std::stoi(m[2]);
}

// Usage errors (exit code 2) before the world is built: the image size, and the output's size
// against the free space where it goes.
void check_synth_options(Options& opt, const CLI::App& cmd) {
  if (cmd.count("--noise-seed") > 0) opt.config.noise_seed = static_cast<uint64_t>(opt.noise_seed);
  if (opt.perfect_rig) {
    for (const char* option : {"--rig-translation-error", "--rig-rotation-error", "--rig-time-offset"})
      if (cmd.count(option) > 0) usage_error(fmt::format("--perfect-rig sets the rig errors to 0: it cannot go with {}", option));
    opt.config.rig_translation_error_m = opt.config.rig_rotation_error_deg = opt.config.rig_time_offset_s = 0;
  }
  if (opt.format != "mcap")
    for (const char* option : {"--compression", "--chunk-size"})
      if (cmd.count(option) > 0) usage_error(fmt::format("{} applies to the recording: it needs --format mcap", option));
  check_as_usage([&] {
    parse_image_size(opt.image_size, opt.config);
    opt.config.validate();
  });
  const auto& c = opt.config;
  const double scans = c.length_m / c.speed_mps * c.lidar_rate_hz, images = c.length_m / c.speed_mps * c.camera_rate_hz;
  // Measured on the defaults: a scan takes about 20 B per ray (points + labels, no-return rays dropped
  // or not), a JPEG + label PNG about 0.5 B per pixel.
  const double folder_bytes = scans * c.lidar.beams * c.lidar.columns * 20.0 +
                              images * static_cast<double>(c.image_width) * c.image_height * 0.5;
  const double bytes = opt.format == "mcap" ? 2 * folder_bytes : folder_bytes;  // the recording holds it all again
  std::error_code ec;
  fs::path existing = fs::absolute(opt.out);
  while (!existing.empty() && !fs::exists(existing, ec) && existing != existing.parent_path())
    existing = existing.parent_path();
  const auto space = fs::space(existing, ec);
  if (!ec && !opt.skip_space_check && bytes > static_cast<double>(space.available))
    throw Error(fmt::format("the sequence would take about {:.1f} MB but {} has {:.1f} MB free (shorten --length)",
                            bytes / 1e6, existing.string(), static_cast<double>(space.available) / 1e6));
  if (bytes > 10e9)
    spdlog::warn("the sequence will take about {:.0f} GB ({:.0f} scans, {:.0f} images)", bytes / 1e9, scans, images);
}

void run(const Options& opt) {
  synth::SynthConfig config = opt.config;
  parse_image_size(opt.image_size, config);
  const auto start = std::chrono::steady_clock::now();
  std::optional<ProgressBar> bar;
  const synth::SynthSummary s =
      synth::write_synthetic_sequence(config, opt.out, opt.force, [&](std::size_t done, std::size_t total) {
        if (!bar) bar.emplace("synth (simulated)", total, "frames");
        bar->update(done);
      });
  if (bar) bar->finish();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("SIMULATED sequence written to %s in %.1f s\n", opt.out.c_str(), seconds);
  std::printf("  scans       %zu (%zu points, %zu no-return rays %s)\n", s.scans, s.points, s.no_returns,
              config.keep_no_return ? "written as zero points" : "dropped");
  std::printf("  images      %zu (%dx%d)\n", s.images, config.image_width, config.image_height);
  std::printf("  path length %.1f m (loop %.1f m, revisited after it)\n", s.path_length_m, s.loop_perimeter_m);
  std::printf("  output size %.1f MB\n", static_cast<double>(s.bytes) / 1e6);
  const fs::path mcap = fs::path(opt.out) / kSynthMcapName;
  if (opt.format == "mcap") {
    write_folder_as_mcap(opt.out, mcap, opt.mcap, "SIMULATED drive");
  } else if (opt.force) {
    std::error_code ec;
    fs::remove(mcap, ec);  // not the recording of an earlier drive beside this one
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "synth",
      "Write a SIMULATED off-road sequence (procedural scene, simulated OS1-64 LiDAR and camera, ground-truth poses "
      "and labels) in the RELLIS-3D folder layout. The data are synthetic, not recorded.");
  cmd->add_option("out_dir", opt->out, "Output directory (missing or empty, unless --force)")->required();
  cmd->add_option("--seed", opt->config.seed, "Random seed; the same seed and settings give identical files")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_option("--length", opt->config.length_m, "Driven path length in metres (a loop, revisited at its end)")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxSynthLength, true));
  cmd->add_option("--speed", opt->config.speed_mps, "Vehicle speed in m/s")
      ->capture_default_str()
      ->check(finite_range(0, 40, true));
  cmd->add_option("--camera-rate", opt->config.camera_rate_hz, "Camera frame rate in Hz (the LiDAR runs at 10 Hz)")
      ->capture_default_str()
      ->check(finite_range(0, 100, true));
  cmd->add_option("--image-size", opt->image_size, "Image size WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--scene", opt->config.scene,
                  "offroad: the loop trail scene; repeated: one arrangement of objects repeated every "
                  "--repeat-spacing metres (look-alike places, for testing loop closure against false loops)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, synth::SceneKind>{
          {"offroad", synth::SceneKind::kOffroad}, {"repeated", synth::SceneKind::kRepeatedPlaces}}))
      ->default_str("offroad");
  cmd->add_option("--repeat-spacing", opt->config.repeat_spacing_m, "Metres between repeated places (--scene repeated)")
      ->capture_default_str();
  cmd->add_option("--min-loop", opt->config.min_loop_m,
                  "Shortest loop built (metres); a loop longer than --length is never revisited")
      ->capture_default_str();
  // Several drives over one scene (issue 23): the same --seed and --loop-length, each drive its own
  // --start-offset, direction and --noise-seed.
  cmd->add_option("--loop-length", opt->config.loop_length_m,
                  "The loop's perimeter in metres (0: from --length and --min-loop); fix it to drive one scene twice "
                  "with different lengths")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxSynthLength));
  cmd->add_option("--start-offset", opt->config.start_offset_m, "Start the drive this many metres along the loop")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxSynthLength));
  cmd->add_flag("--reverse", opt->config.reverse, "Drive the loop clockwise (the scene is the same)");
  cmd->add_option("--noise-seed", opt->noise_seed,
                  "Seed of the SIMULATED sensor noise, camera jitter and rig errors (default: --seed, which keeps "
                  "fixing the scene and the loop)")
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_option("--lidar-columns", opt->config.lidar.columns,
                  "Simulated LiDAR columns per turn (1024; 2048 gives full-size 131k-point OS1-64 scans)")
      ->capture_default_str()
      ->check(integer_range(1, bounds::kMaxLidarColumns));
  cmd->add_option("--lidar-sweep", opt->config.lidar_sweep_s,
                  "SIMULATED rotating sweep (s, e.g. 0.1 at 10 Hz; at most the scan period): each column is cast from "
                  "the pose at its own time after the scan's stamp, and per-point times (uint32 ns since the stamp) "
                  "go to os1_cloud_node_point_times/, which the recording fixture writers' --point-times read. "
                  "0: each scan from one pose")
      ->capture_default_str()
      ->check(finite_range(0, 1));
  cmd->add_flag("--keep-no-return", opt->config.keep_no_return,
                "Write rays without a return as all-zero points, like the real sensor's files");
  cmd->add_option("--rig-translation-error", opt->config.rig_translation_error_m,
                  "SIMULATED camera-LiDAR extrinsic error (m): the images are rendered from a camera this far from "
                  "where transforms.yaml says it is, as a real calibration is off by a few centimetres")
      ->capture_default_str()
      ->check(finite_range(0, 1));
  cmd->add_option("--rig-rotation-error", opt->config.rig_rotation_error_deg,
                  "SIMULATED camera-LiDAR rotation error (degrees), likewise")
      ->capture_default_str()
      ->check(finite_range(0, 10));
  cmd->add_option("--rig-time-offset", opt->config.rig_time_offset_s,
                  "SIMULATED camera time-stamp error (s): each image shows the scene this much later than its stamp")
      ->capture_default_str()
      ->check(finite_range(-0.1, 0.1));
  cmd->add_flag("--perfect-rig", opt->perfect_rig,
                "No SIMULATED rig errors (the three above zero): images rendered exactly where the files say");
  cmd->add_option("--format", opt->format,
                  "folder: the RELLIS-3D folder layout; mcap: the folder and the same drive as a ROS 2 MCAP recording, "
                  "OUT_DIR/drive.mcap (PointCloud2, CompressedImage, CameraInfo, labels, /tf_static, ground-truth "
                  "Odometry; open it in Foxglove, or map it like the folder)")
      ->capture_default_str()
      ->check(CLI::IsMember({"folder", "mcap"}));
  add_mcap_output_options(cmd, opt->mcap);
  cmd->add_flag("--force", opt->force, "Replace a sequence already in OUT_DIR");
  cmd->add_flag("--skip-space-check", opt->skip_space_check,
                "Write even if the estimated size exceeds the free space (the estimate can be wrong on compressing "
                "file systems; a full disk still fails cleanly, leaving an incomplete sequence)");
  add_option_checks(cmd, [opt, cmd] { check_synth_options(*opt, *cmd); });
  auto io = std::make_shared<IoOptions>(cmd);
  io->output_folder("out_dir", opt->out, {}, /*lock=*/true);  // filled for minutes: one run at a time
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_synth
