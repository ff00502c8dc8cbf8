// `slamvdb slam`: a semantic map without ground-truth poses. The project's LiDAR odometry and
// loop-closing mapper give the streaming Mapper each scan's pose as it is registered; when a loop
// is accepted the submaps are moved to the corrected trajectory while mapping goes on (no sensor
// data is fused again) and submaps that a loop shows to be the same place are merged.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <optional>

#include "colour_basis_option.hpp"
#include "command_registry.hpp"
#include "input_options.hpp"
#include "yaml_config.hpp"
#include "feature_options.hpp"
#include "map_option_checks.hpp"
#include "io_options.hpp"
#include "live_serve_option.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "push_option.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/io/trajectory_io.hpp"
#include "slamvdb/localization/trajectory_metrics.hpp"
#include "slamvdb/pipeline/slam_mapping.hpp"
#include "slamvdb/store/map_file_writer.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_slam {
namespace {

struct Options {
  std::string dataset, output, poses_out;
  PoseFormat format = PoseFormat::kKitti;
  FeatureOptions features;
  TrackingOptions tracking;
  PipelineOptions pipeline;
  double min_merge_overlap = MergeOptions{}.min_overlap;
  double max_memory_gb = 0;
  ColourBasisChoice colour_basis;
  std::string fusion_weighting = "paper";
  RecordingOptions recording;
  LiveServeOptions serve;
  PushOption push;
};

// Pose errors of the scans that have a ground-truth pose, after SE(3) alignment.
std::optional<localization::AteResult> ate_against(const Trajectory& truth, const std::vector<double>& stamps,
                                                   const std::vector<Pose>& poses) {
  std::vector<Pose> estimate, reference;
  for (std::size_t i = 0; i < stamps.size(); ++i)
    if (const auto T = truth.at(stamps[i])) estimate.push_back(poses[i]), reference.push_back(*T);
  if (estimate.size() < 3) return std::nullopt;
  return localization::absolute_trajectory_error(estimate, reference);
}

void run(Options opt, const std::string& config) {
  InputOptions input_options = opt.recording.input_options();
  input_options.need_poses = true;  // the ground truth places the odometry frame and measures the error
  const auto input = open_input(opt.dataset, input_options);
  const Sequence& seq = input->sequence();
  print_input(*input);
  const std::size_t scans = input->is_recording() ? input->scan_count() : seq.scans.size();
  if (scans < 3 && !(input->is_recording() && scans == 0))  // a recording without an index: not known
    throw Error(fmt::format("{}: {} scans; slam needs at least 3", opt.dataset, scans));
  std::unique_ptr<FeatureSource> source;
  if (opt.features.features == "none") {
    fmt::print("--features none: geometry only\n");
  } else if (input->is_recording() && !input->has_camera()) {
    fmt::print("no camera in {}: geometry only\n", seq.root.string());
  } else if (input->is_recording() && opt.features.features == "simulated" && !input->has_labels()) {
    throw Error(fmt::format("--features simulated reads SIMULATED label images: {} has no label topic (name one with "
                            "--label-topic, or use --features model)", seq.root.string()));
  } else if (input->is_recording() && opt.features.features == "precomputed") {
    throw Error("--features precomputed reads features/<image>.npy beside a dataset folder: not available for a recording");
  } else {
    source = make_feature_source(opt.features, seq);
  }
  if (opt.tracking.simulated_drift_deg_per_100m != 0.0)
    spdlog::warn("odometry drift is SIMULATED: {} degrees of heading per 100 m are added to the odometry",
                 opt.tracking.simulated_drift_deg_per_100m);

  // Odometry, loop closure and mapping in one pass: each scan's pose goes to the mapper as soon as
  // the scan is registered; accepted loops move (and merge) the submaps while mapping goes on.
  SlamMappingOptions slam_options{opt.pipeline, opt.tracking, MergeOptions{opt.min_merge_overlap}};
  // The map file grows submap by submap while mapping, as in `map`, so that finished submaps far
  // from the vehicle can leave memory (--unload-radius); corrections and merges are kept in step.
  std::optional<LiveServer> live;  // --serve: the map as it is built (bound before any file is written)
  if (!opt.serve.address.empty()) {
    live.emplace(opt.serve, seq.root.string(), opt.pipeline.map.semantic.dim,
                 source && opt.features.features == "simulated" ? std::optional(opt.features.sim_seed) : std::nullopt);
    live->watch(slam_options.pipeline);
  }
  const MapInfo start_info = map_info_for(seq, source.get(), opt.pipeline);
  const OutputTarget target = resolve_output(opt.output);
  const auto push = opt.push.connect(opt.pipeline.map, start_info, opt.output);  // --push: before any work
  auto writer = MapFileWriter::create(opt.output, opt.pipeline.map, start_info);
  slam_options.pipeline.store = writer.get();
  if (push) {  // the file first, then the fleet
    push->keep_in(*writer);
    slam_options.pipeline.store = push.get();
  }
  std::optional<ProgressBar> bar;
  const auto started = std::chrono::steady_clock::now();
  auto progress = [&](std::size_t done, std::size_t total, const TrackingResult& r, const StreamProgress& read) {
    if (!bar) bar.emplace("slam", total, "scans");
    const std::string rate = read_rate(read, started);
    bar->update(done, fmt::format("{:.0f} m{}{}", r.distance,
                                  r.loop_closer ? fmt::format(", {} loops", r.loop_closer->loops().size()) : "",
                                  rate.empty() ? "" : ", " + rate));
    if (live) live->progress(done, total);
  };
  SlamMappingResult run = [&] {
    try {
      return map_with_own_poses(*input, source.get(), slam_options, progress);
    } catch (...) {
      // slam cannot resume a run, so a failed one leaves no partial map file (a device or FIFO
      // gets nothing: the file grew in a temporary).
      writer.reset();
      std::error_code ignored;
      if (!target.is_stream()) std::filesystem::remove(target.resolved, ignored);
      throw;
    }
  }();
  if (bar) bar->finish();
  const TrackingResult& tracked = run.tracked;
  for (const auto& line : tracked.problems) spdlog::warn("{}", escape_control(line));
  fmt::print("{}\n", escape_control_keep_lines(run.report.summary()));
  SemanticMap& map = run.map;
  const std::vector<Pose> odometry_poses = run.odometry_poses(), corrected_poses = run.corrected_poses();
  const LoopCorrectionReport& corrections = run.corrections;
  MapInfo info = map.info();
  info.source = "slam (own odometry" + std::string(tracked.loop_closer ? " + loop closure" : "") +
                (opt.tracking.simulated_drift_deg_per_100m != 0.0
                     ? fmt::format(", SIMULATED drift {} deg/100 m", opt.tracking.simulated_drift_deg_per_100m)
                     : "") +
                "): " + seq.root.string();
  info.config = config;
  map.set_info(info);
  record_colour_basis(map, opt.colour_basis);
  // With submaps unloaded, memory holds only part of the map: its size is then not recorded.
  const MapFileSummary saved = writer->finish(map.info(), run.report.submaps_unloaded ? 0 : map.memory_bytes());
  if (!opt.poses_out.empty()) write_trajectory(opt.poses_out, tracked.stamps, corrected_poses, opt.format);

  fmt::print("slam of {}: {} scans, {:.1f} m, tracking {:.1f} scans/s{}\n", opt.dataset, tracked.stamps.size(),
             tracked.distance, tracked.stamps.size() / std::max(tracked.busy_seconds, 1e-9),
             opt.tracking.simulated_drift_deg_per_100m != 0.0
                 ? fmt::format(" (SIMULATED odometry drift {} deg / 100 m)", opt.tracking.simulated_drift_deg_per_100m)
                 : "");
  fmt::print("  registered   {} ({} after a wide retry)\n", tracked.registered(), tracked.recovered);
  for (const auto& [reason, n] : tracked.failures) fmt::print("  not registered ({}): {}\n", reason, n);
  if (tracked.loop_closer) {
    fmt::print("  loops        {} accepted, {} rejected\n", tracked.loop_closer->loops().size(),
               tracked.loop_closer->rejected_total());
  }
  fmt::print("  submaps      {} moved by {} corrections while mapping (largest shift {:.2f} m), {} merged, {} merges "
             "refused\n", corrections.submaps_moved, corrections.corrections, corrections.max_shift, corrections.merges,
             corrections.merges_refused);
  for (const auto& note : corrections.notes) fmt::print("    {}\n", note);
  if (!seq.poses.empty()) {
    const auto before = ate_against(seq.poses, tracked.stamps, odometry_poses);
    const auto after = ate_against(seq.poses, tracked.stamps, corrected_poses);
    if (before && after)
      fmt::print("  against the dataset's poses: ATE rmse {:.3f} m with odometry only, {:.3f} m after loop closure\n",
                 before->rmse, after->rmse);
  }
  fmt::print("map saved to {}: {} submaps, {} semantic entries{}\n", opt.output, saved.submaps.size(),
             saved.semantic_voxels, opt.poses_out.empty() ? "" : "; poses written to " + opt.poses_out);
  finish_push(push.get(), opt.push, map.info(), opt.output);
  if (live) live->finish(std::move(map));  // last: it takes the map
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "slam",
      "Map a dataset (RELLIS-3D or KITTI layout) or a recording (ROS 1 bag, ROS 2 bag, MCAP) without its poses: LiDAR odometry gives the mapper each scan's pose "
      "as it is registered; when loop closure accepts a loop, the submaps are moved to the corrected trajectory while "
      "mapping goes on (and merged where a loop shows two are the same place).");
  cmd->add_option("dataset", opt->dataset,
                  "Sequence directory, or a recording: ROS 1 .bag, .mcap, ROS 2 bag folder or .db3")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("-o,--output", opt->output, "Map file to write (.svdb)")->required();
  cmd->add_option("--poses-out", opt->poses_out, "Also write the corrected poses (T_world_lidar per scan)");
  cmd->add_option("--format", opt->format, "Format of --poses-out: kitti or tum")
      ->transform(CLI::CheckedTransformer(std::map<std::string, PoseFormat>{{"kitti", PoseFormat::kKitti},
                                                                             {"tum", PoseFormat::kTum}}))
      ->default_str("kitti");
  add_feature_options(cmd, opt->features, false, false, /*with_none=*/true);
  cmd->add_flag("--no-loop-closure", [opt](std::int64_t n) { opt->tracking.loop_closure = n <= 0; },
                "Odometry only (no submap moves or merges)");
  cmd->add_flag("--no-deskew",
                [opt](std::int64_t n) {
                  opt->pipeline.deskew = n <= 0;
                  opt->tracking.odometry.deskew = n <= 0;
                },
                "Fuse scans with per-point times as read, without moving each point to where the sensor was at the "
                "scan's pose (by default they are deskewed with the odometry's motion estimate); the odometry does not "
                "deskew either");
  cmd->add_flag("--realtime", opt->pipeline.realtime,
                "Replay at sensor rate on the wall clock: each scan is taken at its stamp; one that a newer scan "
                "overtook while the odometry worked is skipped (as a driver's queue of one would), frames that find "
                "the mapper's queue full are dropped, all counted in the report. Default: every scan, as fast as it "
                "goes");
  cmd->add_option("--sim-odometry-drift", opt->tracking.simulated_drift_deg_per_100m,
                  "SIMULATED odometry drift: degrees of heading error added per 100 m travelled, to see loop closure "
                  "correct a drive whose odometry hardly drifts")
      ->capture_default_str()
      ->check(finite_range(-90, 90));
  cmd->add_option("--keyframe-distance", opt->tracking.loops.keyframe_distance, "Metres of path between keyframes")
      ->capture_default_str()
      ->check(finite_range(0.1, 100));
  cmd->add_option("--submap-length", opt->pipeline.map.submap_length, "Metres of path per submap (0: one submap)")
      ->capture_default_str()
      ->check(finite_range(0, 1e6));
  cmd->add_option("--voxel-size", opt->pipeline.map.occupancy.voxel_size, "Map voxel edge (m)")
      ->capture_default_str()
      ->check(finite_range(bounds::kMinVoxelSize, bounds::kMaxVoxelSize));
  cmd->add_option("--min-merge-overlap", opt->min_merge_overlap,
                  "Merge two submaps joined by a loop when this share of occupied voxels agrees")
      ->capture_default_str()
      ->check(finite_range(0, 1));
  opt->pipeline.unload_radius = kDefaultUnloadRadius;
  cmd->add_option("--unload-radius", opt->pipeline.unload_radius,
                  "Finished submaps whose anchor is farther than this (m) from the vehicle leave memory (they are in "
                  "the map file, which grows while mapping) and come back when needed (0: keep all in memory)")
      ->capture_default_str()
      ->check(finite_range(0, 1e7));
  add_fusion_weighting_option(cmd, opt->fusion_weighting);
  add_max_memory_option(cmd, opt->max_memory_gb);
  add_colour_basis_option(cmd, opt->colour_basis);
  opt->recording.add_to(cmd);
  opt->serve.add_to(cmd);
  opt->push.add_to(cmd);
  add_option_checks(cmd, [opt] {
    opt->serve.check();
    if (!opt->push.session.empty() && opt->push.url.empty()) usage_error("--push-session goes with --push");
    check_feature_options(opt->features);
    opt->pipeline.map.semantic.dim = opt->features.dim;
    set_fusion_weighting(opt->pipeline, opt->fusion_weighting);
    // The same checks as `map`: the feature maps, the voxel counts, the memory of one scan.
    const bool fp32 = opt->pipeline.map.semantic.precision == EmbeddingPrecision::kFloat32;
    check_map_options(opt->pipeline, MappingChoices{opt->features.features, opt->features.feature_size, "fp32",
                                                    fp32 ? "fp32" : "fp16", "", opt->max_memory_gb});
    check_colour_basis_option(opt->colour_basis, opt->features.dim);
    check_as_usage([&] {
      opt->tracking.odometry.validate();  // the tracking checks `odometry` runs too
      opt->tracking.loops.validate();
      opt->pipeline.map.validate();
    });
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("dataset", opt->dataset);
  io->input("--colour-basis", opt->colour_basis.file);
  io->input("--extrinsics", opt->recording.extrinsics);
  add_feature_inputs(*io, opt->features);
  io->output("-o", opt->output, {}, /*lock=*/true);  // one run at a time
  io->output("--poses-out", opt->poses_out);
  cmd->callback([opt, cmd, io] {
    io->check();
    run(*opt, effective_config(*cmd));
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_slam
