// `slamvdb odometry`: LiDAR odometry (KISS-ICP-style) over a dataset folder, a folder of scan
// files or a robot recording, optionally with loop closure (ScanContext + ICP verification + pose graph); writes the
// poses T_world_sensor (world = the first scan's sensor frame) in KITTI or TUM format.
#include <fmt/format.h>
#include <tbb/global_control.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "command_registry.hpp"
#include "input_options.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/trajectory_io.hpp"
#include "slamvdb/localization/loop_closure.hpp"
#include "slamvdb/localization/odometry.hpp"
#include "slamvdb/pipeline/lidar_tracking.hpp"

namespace slamvdb::cli::cmd_odometry {
namespace {

using namespace slamvdb::localization;

struct Options {
  std::string input, output, json;
  PoseFormat format = PoseFormat::kKitti;
  bool loop_closure = false;
  double rate_hz = 10.0;
  OdometryConfig odometry;
  double keyframe_distance = 2.0;
  int max_consecutive_failures = 10;
  int threads = 0;
  RecordingOptions recording;
};

void run(const Options& opt) {
  std::optional<tbb::global_control> threads;
  if (opt.threads > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, opt.threads);
  InputOptions input_options = opt.recording.input_options();
  input_options.scans_only = true;
  input_options.rate_hz = opt.rate_hz;
  const auto input = open_input(opt.input, input_options);
  for (const auto& note : input->sequence().notes) fmt::print(stderr, "note: {}\n", escape_control(note));
  TrackingOptions tracking;
  tracking.odometry = opt.odometry;
  tracking.loop_closure = opt.loop_closure;
  tracking.loops.keyframe_distance = opt.keyframe_distance;
  tracking.max_consecutive_failures = opt.max_consecutive_failures;
  LidarTracker tracker(tracking);
  ProgressBar bar("odometry", input->scan_count(), "scans");
  const auto stream = input->open(false);
  const auto started = std::chrono::steady_clock::now();
  SensorFrame scan;
  for (std::size_t i = 0; stream->next(scan);) {
    if (scan.kind != SensorFrame::Kind::kScan) continue;
    if (!scan.error.empty()) throw Error(scan.error);  // as before: an unreadable scan file stops the run
    const std::size_t problems = tracker.result().problems.size();
    try {
      tracker.track(scan.stamp, scan.points, scan.point_times.empty() ? nullptr : &scan.point_times, scan.name);
    } catch (const Error& e) {
      throw Error(fmt::format("{}; poses not written", e.what()));
    }
    const TrackingResult& r = tracker.result();
    if (r.problems.size() > problems) fmt::print(stderr, "\n{}\n", escape_control(r.problems.back()));
    const std::string rate = read_rate(stream->progress(), started);
    ++i;
    bar.update(i, fmt::format("{:.0f} m, {:.1f} Hz{}{}", r.distance, i / std::max(r.busy_seconds, 1e-9),
                                r.loop_closer ? fmt::format(", {} loops", r.loop_closer->loops().size()) : "",
                                rate.empty() ? "" : ", " + rate));
  }
  for (const auto& line : stream->skipped()) fmt::print(stderr, "input: {}\n", escape_control(line));
  bar.finish();
  tracker.require_registered(opt.input);  // poses that are all guesses are not written
  const TrackingResult r = tracker.take_result();
  std::vector<Pose> poses;
  for (std::size_t i = 0; i < r.stamps.size(); ++i) poses.push_back(r.corrected(i));
  write_trajectory(opt.output, r.stamps, poses, opt.format);

  fmt::print("odometry of {} ({}): {} scans, {:.1f} m, {:.1f} scans/s\n", opt.input, input->kind(), poses.size(),
             r.distance, poses.size() / std::max(r.busy_seconds, 1e-9));
  fmt::print("  registered   {} ({} after a wide retry)\n", r.registered(), r.recovered);
  for (const auto& [reason, n] : r.failures) fmt::print("  not registered ({}): {} (prediction used)\n", reason, n);
  fmt::print("  points dropped: {} non-finite, {} out of range\n", r.non_finite_points, r.out_of_range_points);
  nlohmann::json summary = {{"input", opt.input},  {"scans", poses.size()}, {"distance_m", r.distance},
                            {"registered", r.registered()}, {"recovered", r.recovered},
                            {"not_registered", r.failures}, {"loop_closure", opt.loop_closure}};
  if (const LoopClosingMapper* mapper = r.loop_closer.get()) {
    fmt::print("  keyframes    {}\n  loops        {} accepted, {} rejected", mapper->keyframes().size(),
               mapper->loops().size(), mapper->rejected_total());
    nlohmann::json rejected = nlohmann::json::object(), loops = nlohmann::json::array();
    for (std::size_t k = 0; k < mapper->rejections().size(); ++k) {
      const char* reason = to_string(static_cast<LoopRejection>(k));
      rejected[reason] = mapper->rejections()[k];
      if (mapper->rejections()[k] > 0) fmt::print(" ({}: {})", reason, mapper->rejections()[k]);
    }
    fmt::print("\n");
    for (const LoopClosure& l : mapper->loops())
      loops.push_back({{"candidate_stamp", l.candidate_stamp}, {"query_stamp", l.query_stamp}, {"overlap", l.overlap},
                       {"rmse", l.rmse}, {"scan_context", l.from_scan_context}});
    summary["keyframes"] = mapper->keyframes().size();
    summary["loops"] = loops;
    summary["loops_rejected"] = rejected;
  }
  fmt::print("  poses written to {} ({})\n", opt.output, opt.format == PoseFormat::kKitti ? "KITTI" : "TUM");
  if (!opt.json.empty()) write_output_file(opt.json, summary.dump(2) + "\n");
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "odometry",
      "LiDAR odometry (KISS-ICP-style scan-to-local-map ICP) over a dataset folder (RELLIS-3D or KITTI layout), a "
      "recording (ROS 1 bag, ROS 2 bag, MCAP) or a folder of scan files (KITTI .bin or .pcd, in name order; stamps from times.txt there, else index / --rate), "
      "optionally with loop closure; writes T_world_sensor per scan (world = the first scan's sensor frame).");
  cmd->add_option("input", opt->input, "Dataset folder, folder of .bin / .pcd scans, or a recording (.bag, .mcap, ROS 2 bag)")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("-o,--output", opt->output, "Pose file to write")->required();
  cmd->add_option("--format", opt->format, "Pose file format: kitti (3x4 rows) or tum (stamp tx ty tz qx qy qz qw)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, PoseFormat>{{"kitti", PoseFormat::kKitti},
                                                                             {"tum", PoseFormat::kTum}}))
      ->default_str("kitti");
  cmd->add_flag("--loop-closure", opt->loop_closure,
                "Close loops (ScanContext + proximity candidates, ICP verification, pose graph) and write the "
                "corrected poses");
  cmd->add_option("--json", opt->json, "Also write a JSON summary (counts, accepted loops)");
  cmd->add_option("--rate", opt->rate_hz, "Scan rate (Hz) for stamping a folder without times.txt")
      ->check(finite_range(0, 1e6, true))->capture_default_str();
  cmd->add_option("--voxel-size", opt->odometry.voxel_size, "Local-map voxel (m)")->check(finite_range(0.05, 10.0))->capture_default_str();
  cmd->add_option("--max-range", opt->odometry.max_range, "Farthest return used (m)")->check(finite_range(1.0, 1000.0))->capture_default_str();
  cmd->add_option("--min-range", opt->odometry.min_range, "Nearest return used (m)")->check(finite_range(0.0, 100.0))->capture_default_str();
  cmd->add_option("--keyframe-distance", opt->keyframe_distance, "Metres of path between loop-closure keyframes")
      ->check(finite_range(0.1, 100.0))->capture_default_str();
  cmd->add_option("--max-consecutive-failures", opt->max_consecutive_failures,
                  "Fail when more scans than this in a row cannot be registered")
      ->check(integer_range(0, bounds::kMaxCount))->capture_default_str();
  cmd->add_option("--threads", opt->threads, "Worker threads (0: all cores)")->check(integer_range(0, bounds::kMaxThreads));
  // The tracking checks `slam` runs too (the library's own).
  opt->recording.add_to(cmd);
  add_option_checks(cmd, [opt] { check_as_usage([&] { opt->odometry.validate(); }); });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("input", opt->input);
  io->output("-o", opt->output);
  io->output("--json", opt->json);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_odometry
