// `slamvdb map`: replays a dataset (RELLIS-3D or KITTI layout) or a robot recording (ROS 1 bag, ROS 2
// bag, MCAP) into a semantic voxel map file.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <memory>
#include <optional>
#include <regex>

#include "colour_basis_option.hpp"
#include "command_registry.hpp"
#include "input_options.hpp"
#include "io_options.hpp"
#include "live_serve_option.hpp"
#include "yaml_config.hpp"
#include "map_option_checks.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "push_option.hpp"
#include "sim_encoder_options.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/inference/torch_backend.hpp"
#include "slamvdb/store/map_file_writer.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/pipeline/pose_source.hpp"

namespace slamvdb::cli::cmd_map {
namespace {

struct Options {
  std::string dataset, output;
  std::string features = "simulated";
  std::string precision = "fp16";
  std::string sim_feature_precision = "fp32";
  std::string feature_size = "192x128";
  std::string distortion;
  std::string model;
  int threads = -1;
  PipelineOptions pipeline;
  SimulatedEncoderConfig sim;
  SimEncoderOptions sim_encoder;
  bool realtime = false, resume = false, no_checkpoints = false;
  std::string poses, pose_format = "auto";
  bool odometry = false;
  TrackingOptions tracking;
  double queue_mb = 1024;
  double max_memory_gb = 0;
  std::string occlusion = "active";
  std::string fusion_weighting = "paper";
  double max_image_pixels = static_cast<double>(kDefaultMaxImagePixels);
  ColourBasisChoice colour_basis;
  RecordingOptions recording;
  LiveServeOptions serve;
  PushOption push;
};

std::unique_ptr<FeatureSource> make_feature_source(const Options& opt, const SensorInput& input) {
  if (opt.features == "none") return nullptr;
  const Sequence& seq = input.sequence();
  if (input.is_recording() && !input.has_camera()) {
    fmt::print("no camera in {}: geometry only (--features {} not used)\n", seq.root.string(), opt.features);
    return nullptr;
  }
  if (input.is_recording() && opt.features == "simulated" && !input.has_labels())
    throw Error(fmt::format("--features simulated reads SIMULATED label images: {} has no label topic (name one with "
                            "--label-topic, or map with --features none or model)", seq.root.string()));
  if (input.is_recording() && opt.features == "precomputed")
    throw Error("--features precomputed reads features/<image>.npy beside a dataset folder: not available for a recording");
  if (!opt.model.empty() && opt.features != "model")
    throw Error("--model is given: use it with --features model");
  if (opt.features == "model") {
    if (opt.model.empty()) throw Error("--features model needs --model MODEL.pt (TorchScript dense encoder + manifest)");
    auto encoder = open_torch_dense_image_encoder(opt.model, TorchEncoderOptions{.threads = opt.threads});
    fmt::print("network {}: {}-d features\n", escape_control(encoder->model_id()), encoder->dim());
    return std::make_unique<EncoderFeatureSource>(std::move(encoder), EncoderFeatureSource::Input::kRgb);
  }
  if (opt.features == "precomputed") {
    for (const auto& img : seq.images)
      if (!img.features.empty()) return std::make_unique<NpyFeatureSource>("precomputed:" + seq.root.string());
    throw Error(fmt::format("--features precomputed: no features/<image>.npy files in {}", seq.root.string()));
  }
  if (opt.features == "simulated") {
    SimulatedEncoderConfig sim = opt.sim_encoder.config(opt.sim);
    static const std::regex kSize(R"((\d{1,5})[xX](\d{1,5}))");
    std::smatch m;
    if (!std::regex_match(opt.feature_size, m, kSize))
      throw Error(fmt::format("--feature-size '{}' is not WIDTHxHEIGHT", opt.feature_size));
    sim.width = std::stoi(m[1]);
    sim.height = std::stoi(m[2]);
    sim.dim = opt.pipeline.map.semantic.dim;
    sim.output_precision = precision_from_string(opt.sim_feature_precision);
    spdlog::warn("features are SIMULATED from the 2D label images (no network): {}; encoder {}", simulated_model_id(sim),
                 sim.describe());
    warn_missing_view_geometry(seq, sim);
    if (input.is_recording())
      spdlog::warn("a recording carries no SIMULATED view geometry: the SIMULATED encoder's range and grazing errors "
                   "are off and its persistent errors follow the image, not the world");
    return std::make_unique<EncoderFeatureSource>(std::make_unique<SimulatedDenseEncoder>(sim),
                                                  EncoderFeatureSource::Input::kLabels);
  }
  throw Error(fmt::format("--features '{}': expected simulated, model, precomputed or none", opt.features));
}

// A run continues a map file only with the parameters that made it (a voxel of another size or an
// embedding of another model, fused by another rule or from an encoder with other settings would
// not be the same map); the first difference is named.
void check_resumable(const SemanticMap& map, const MapParams& p, const MapInfo& run, const Sequence& seq,
                     const std::string& file) {
  const MapParams& f = map.params();
  const std::pair<const char*, bool> same[] = {
      {"--voxel-size", f.occupancy.voxel_size == p.occupancy.voxel_size},
      {"--dim", f.semantic.dim == p.semantic.dim},
      {"--precision", f.semantic.precision == p.semantic.precision},
      {"--fusion-weighting single-view", f.semantic.single_view == p.semantic.single_view},
      {"--submap-length", f.submap_length == p.submap_length},
      {"--min-range", f.occupancy.min_point_range == p.occupancy.min_point_range},
      {"--max-range", f.occupancy.max_point_range == p.occupancy.max_point_range},
      {"--max-clearing-range", f.occupancy.max_clearing_range == p.occupancy.max_clearing_range},
      {"log-odds parameters", f.occupancy.log_odds_hit == p.occupancy.log_odds_hit &&
                                  f.occupancy.log_odds_miss == p.occupancy.log_odds_miss &&
                                  f.occupancy.clamp_min == p.occupancy.clamp_min &&
                                  f.occupancy.clamp_max == p.occupancy.clamp_max},
      {"index cell size", f.index_cell() == p.index_cell()}};
  for (const auto& [what, equal] : same)
    if (!equal) throw Error(fmt::format("--resume: {} differs from the run that made {}; give the same options", what, file));
  if (map.info().model_id != run.model_id)
    throw Error(fmt::format("--resume: {} holds embeddings of '{}', this run's features are '{}'", file,
                            escape_control(map.info().model_id), escape_control(run.model_id)));
  if (map.info().fusion != run.fusion)
    throw Error(fmt::format("--resume: {} was fused with the '{}' rule, this run's --fusion-weighting is '{}'", file,
                            escape_control(map.info().fusion), run.fusion));
  // The model id names the embedding space only: the SIMULATED encoder's failure modes
  // (--sim-encoder, --sim-*) are in its recorded settings.
  if (map.info().features != run.features)
    throw Error(fmt::format("--resume: {} was made with the encoder settings '{}', this run's are '{}' (give the same "
                            "--sim-encoder and --sim-* options)",
                            file, escape_control(map.info().features), escape_control(run.features)));
  std::error_code ec;
  if (std::filesystem::weakly_canonical(map.info().source, ec) != std::filesystem::weakly_canonical(seq.root, ec))
    throw Error(fmt::format("--resume: {} was made from {}, not {}", file, escape_control(map.info().source),
                            seq.root.string()));
}

void run(Options opt, const std::string& config) {
  opt.pipeline.fusion.occlusion_from_other_submaps = opt.occlusion == "all";
  set_fusion_weighting(opt.pipeline, opt.fusion_weighting);
  opt.pipeline.map.semantic.precision = precision_from_string(opt.precision);
  opt.pipeline.map.validate();
  ReadOptions read_options;
  if (!opt.distortion.empty()) read_options.distortion = parse_distortion_option(opt.distortion);
  read_options.max_image_pixels = static_cast<std::int64_t>(opt.max_image_pixels);
  InputOptions input_options = opt.recording.input_options();
  input_options.read = read_options;
  input_options.need_poses = opt.poses.empty() && !opt.odometry;  // (--pose-frame: poses from tf)
  const auto input = open_input(opt.dataset, input_options);
  const Sequence& seq = input->sequence();
  print_input(*input);
  std::optional<LiveServer> live;  // --serve: the map as it is built (bound before any file is written)
  if (!opt.serve.address.empty()) {
    live.emplace(opt.serve, seq.root.string(), opt.pipeline.map.semantic.dim,
                 opt.features == "simulated" ? std::optional(opt.sim.seed) : std::nullopt);
    live->watch(opt.pipeline);
  }
  opt.pipeline.realtime = opt.realtime;
  opt.pipeline.queue_bytes = static_cast<std::size_t>(opt.queue_mb * 1e6);
  const auto source = make_feature_source(opt, *input);
  MapInfo info = map_info_for(seq, source.get(), opt.pipeline);
  info.config = config;
  const auto push = opt.push.connect(opt.pipeline.map, info, opt.output);  // --push: checked before any long work
  std::unique_ptr<PoseSource> pose_source = std::make_unique<DatasetPoses>();
  std::optional<ProgressBar> odometry_bar;
  if (!opt.poses.empty())
    pose_source = std::make_unique<PoseFile>(opt.poses, opt.pose_format == "auto" ? std::nullopt
                                                                                   : parse_pose_format(opt.pose_format));
  OdometryPoses* own_poses = nullptr;
  if (opt.odometry && opt.poses.empty()) {
    auto odometry = std::make_unique<OdometryPoses>(
        opt.tracking, [&](std::size_t done, std::size_t total, const TrackingResult& r) {
          if (!odometry_bar) odometry_bar.emplace("odometry", total, "scans");
          odometry_bar->update(done, fmt::format("{:.0f} m", r.distance));
        });
    own_poses = odometry.get();
    pose_source = std::move(odometry);
  }
  const Trajectory poses = pose_source->trajectory(*input);
  if (odometry_bar) odometry_bar->finish();
  if (own_poses)
    for (const auto& line : own_poses->problems()) spdlog::warn("{}", escape_control(line));
  opt.pipeline.poses = &poses;
  if (own_poses) opt.pipeline.sweeps = &own_poses->sweeps();  // deskewed as the odometry deskewed them
  fmt::print("poses: {} ({} poses)\n", pose_source->describe(), poses.size());

  std::optional<SemanticMap> start;
  std::unique_ptr<MapFileWriter> writer;
  if (opt.resume) {
    start.emplace(load_map(opt.output));
    check_resumable(*start, opt.pipeline.map, info, seq, opt.output);
    double end = -1e300;
    for (const SubmapInfo& s : start->submaps()) end = std::max(end, s.time_range.end);
    fmt::print("resuming {}: {} finished submaps, mapped up to {:.3f} s\n", opt.output, start->num_submaps(),
               start->num_submaps() ? end : 0.0);
    writer = MapFileWriter::open_existing(opt.output);
  } else {
    start.emplace(opt.pipeline.map, info);
    if (!opt.no_checkpoints) writer = MapFileWriter::create(opt.output, opt.pipeline.map, info);
  }
  opt.pipeline.store = writer.get();
  if (push) {  // the file first, then the fleet; a resumed run's submaps too (the last may be missing)
    push->keep_in(*writer);
    push->push_existing(*start);
    opt.pipeline.store = push.get();
  }

  std::optional<ProgressBar> bar;
  PipelineReport report;
  const auto started = std::chrono::steady_clock::now();
  SemanticMap map = continue_map(std::move(*start), *input, source.get(), opt.pipeline, report,
                                 [&](std::size_t done, std::size_t total, const StreamProgress& read) {
                                   if (!bar) bar.emplace("map", total, "scans");
                                   bar->update(done, read_rate(read, started));
                                   if (live) live->progress(done, total);
                                 });
  if (bar) bar->finish();
  fmt::print("{}\n", escape_control_keep_lines(report.summary()));
  MapInfo final_info = map.info();
  final_info.config = config;  // the map says how it was made
  map.set_info(final_info);
  record_colour_basis(map, opt.colour_basis);
  // What the file holds (with submaps unloaded during the run, more than memory does now, whose
  // size is then not recorded).
  const MapFileSummary saved = writer ? writer->finish(map.info(), report.submaps_unloaded ? 0 : map.memory_bytes())
                                      : save_map(opt.output, map);
  fmt::print("map saved to {}: {} submaps, {} occupied voxels, {} semantic entries ({} {}-d), {:.1f} MB file{}\n",
             opt.output, saved.submaps.size(), saved.occupied_voxels, saved.semantic_voxels, opt.precision,
             map.params().semantic.dim, saved.file_bytes / 1e6,
             report.submaps_unloaded ? ""
                                     : fmt::format(", {} world cells in the global index, {:.1f} MB in memory",
                                                   map.num_index_cells(), map.memory_bytes() / 1e6));
  finish_push(push.get(), opt.push, map.info(), opt.output);
  if (live) live->finish(std::move(map));  // last: it takes the map
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand("map",
                                  "Build a semantic voxel map from a dataset directory (RELLIS-3D or KITTI layout) "
                                  "or a recording (ROS 1 bag, ROS 2 bag, MCAP) with its ground-truth poses, and save "
                                  "it as one map file");
  cmd->add_option("dataset", opt->dataset,
                  "Sequence directory, or a recording: ROS 1 .bag, .mcap, ROS 2 bag folder or .db3")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("-o,--output", opt->output,
                  "Map file to write: started anew (an old file is replaced atomically) and grown by each finished "
                  "submap, so a killed run leaves every submap finished before the kill (see --resume)")->required();
  cmd->add_option("--features", opt->features,
                  "Where image features come from: 'simulated' (SIMULATED from the 2D label images, no network), "
                  "'model' (a TorchScript dense encoder, --model), 'precomputed' (features/<image>.npy, C x H x W), "
                  "'none' (geometry only)")
      ->capture_default_str()
      ->check(CLI::IsMember({"simulated", "model", "precomputed", "none"}));
  cmd->add_option("--model", opt->model, "TorchScript dense image encoder (MODEL.pt with MODEL.json beside it)");
  cmd->add_option("--threads", opt->threads, "Network threads (-1: the manifest's setting)")
      ->capture_default_str()
      ->check(integer_range(-1, bounds::kMaxThreads));
  auto& m = opt->pipeline.map;
  cmd->add_option("--voxel-size", m.occupancy.voxel_size, "Voxel edge in metres (warns with a memory estimate below 0.1)")
      ->capture_default_str()
      ->check(finite_range(bounds::kMinVoxelSize, bounds::kMaxVoxelSize));
  cmd->add_option("--submap-length", m.submap_length,
                  "Start a new submap after this many metres of path (0: one submap for the whole run)")
      ->capture_default_str()
      ->check(finite_range(0, 1e6));
  cmd->add_option("--occlusion", opt->occlusion,
                  "Which voxels occlude during fusion: 'active' (the submap being written) or 'all' (also the "
                  "finished submaps near the camera)")
      ->capture_default_str()
      ->check(CLI::IsMember({"active", "all"}));
  add_fusion_weighting_option(cmd, opt->fusion_weighting);
  cmd->add_option("--dim", m.semantic.dim, "Embedding dimension")
      ->capture_default_str()
      ->check(integer_range(1, bounds::kMaxDim));
  cmd->add_option("--precision", opt->precision, "Embedding storage: fp16 or fp32")
      ->capture_default_str()
      ->check(CLI::IsMember({"fp16", "fp32"}));
  cmd->add_option("--min-range", m.occupancy.min_point_range, "Drop returns closer than this (m)")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxRange));
  cmd->add_option("--max-range", m.occupancy.max_point_range, "Returns farther only clear space (m)")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxRange, true));
  cmd->add_option("--max-clearing-range", m.occupancy.max_clearing_range, "Clear space along the first metres of each ray")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxRange));
  cmd->add_option("--max-depth", opt->pipeline.fusion.max_depth, "Fuse features into voxels up to this distance (m)")
      ->capture_default_str()
      ->check(finite_range(0, bounds::kMaxRange, true));
  cmd->add_option("--max-scans", opt->pipeline.max_scans, "Map only the first N scans (0: all)")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxCount));
  cmd->add_option("--distortion", opt->distortion, "Camera plumb_bob coefficients 'k1 k2 p1 p2 k3' (overrides the dataset)");
  cmd->add_option("--feature-size", opt->feature_size, "Simulated feature map size WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--sim-seed", opt->sim.seed, "Seed of the simulated encoder")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_option("--sim-feature-precision", opt->sim_feature_precision,
                  "Precision of the SIMULATED feature maps handed to fusion: fp32, or fp16 as a network run in half "
                  "precision gives them (the fp32 values rounded; fusion reads half the bytes). Networks and .npy "
                  "files hand over their own precision")
      ->capture_default_str()
      ->check(CLI::IsMember({"fp32", "fp16"}));
  opt->sim_encoder.add_to(cmd);
  cmd->add_option("--queue", opt->pipeline.queue_capacity,
                  "Most scans and images (with their feature maps) waiting in the mapper at once")
      ->capture_default_str()
      ->check(integer_range(1, bounds::kMaxQueue));
  cmd->add_option("--max-image-pixels", opt->max_image_pixels,
                  "Refuse camera and label images larger than this (from their headers, before decoding)")
      ->capture_default_str()
      ->check(finite_range(1, bounds::kMaxImagePixels));
  cmd->add_option("--queue-mb", opt->queue_mb, "Most megabytes of scans and feature maps waiting in the mapper")
      ->capture_default_str()
      ->check(finite_range(1, 1e6));
  cmd->add_flag("--realtime", opt->realtime,
                "Replay at sensor rate on the wall clock (scan and image stamps); frames that find the mapper's queue "
                "full are dropped and counted, and the report says how many it kept up with. Default: every frame, "
                "as fast as it goes");
  cmd->add_option("--poses", opt->poses,
                  "LiDAR poses in the world from a trajectory file instead of the sequence's ground truth: KITTI "
                  "(3x4 rows, row i = scan i) or TUM (stamp tx ty tz qx qy qz qw)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--odometry", opt->odometry,
                "Poses from the project's own LiDAR odometry and loop closure, computed over the scans before mapping "
                "(placed at the first ground-truth pose when the sequence has one). `slamvdb slam` does both in one "
                "pass instead");
  cmd->add_flag("--no-loop-closure", [opt](std::int64_t n) { opt->tracking.loop_closure = n <= 0; },
                "With --odometry: odometry only");
  cmd->add_flag("--no-deskew",
                [opt](std::int64_t n) {
                  opt->pipeline.deskew = n <= 0;
                  opt->tracking.odometry.deskew = n <= 0;
                },
                "Fuse scans with per-point times as read, without moving each point to where the sensor was at the "
                "scan's pose (by default they are deskewed with the poses' motion, with --odometry the odometry's "
                "trajectory); the odometry does not deskew either");
  cmd->add_option("--pose-format", opt->pose_format, "Format of --poses: auto (from the first row), kitti or tum")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "kitti", "tum"}));
  cmd->add_flag("--resume", opt->resume,
                "Continue the map file -o that a killed run left (it holds every submap finished before the kill): "
                "mapping restarts after its last finished submap, with the same options");
  cmd->add_flag("--no-checkpoints", opt->no_checkpoints,
                "Write the map file once at the end (atomically) instead of submap by submap while mapping");
  opt->pipeline.unload_radius = kDefaultUnloadRadius;
  cmd->add_option("--unload-radius", opt->pipeline.unload_radius,
                  "Finished submaps whose anchor is farther than this (m) from the vehicle leave memory (they are in "
                  "the map file) and come back when it returns, so memory stays bounded on long drives (0: keep all "
                  "in memory; --no-checkpoints also keeps all)")
      ->capture_default_str()
      ->check(finite_range(0, 1e7));
  add_max_memory_option(cmd, opt->max_memory_gb);
  add_colour_basis_option(cmd, opt->colour_basis);
  opt->recording.add_to(cmd);
  opt->serve.add_to(cmd, true);  // continue_map calls first_submap_finished
  opt->push.add_to(cmd);
  add_option_checks(cmd, [opt, cmd] {
    opt->serve.check();
    check_map_options(opt->pipeline, MappingChoices{opt->features, opt->feature_size, opt->sim_feature_precision,
                                                    opt->precision, opt->distortion, opt->max_memory_gb});
    check_colour_basis_option(opt->colour_basis, opt->pipeline.map.semantic.dim);
    if (opt->resume && opt->no_checkpoints) usage_error("--resume continues a map file written submap by submap: it "
                                                        "cannot go with --no-checkpoints");
    if (opt->resume && !std::filesystem::is_regular_file(opt->output))
      usage_error(fmt::format("--resume: there is no map file {} to continue", opt->output));
    if (!opt->push.url.empty() && opt->no_checkpoints)
      usage_error("--push pushes each submap from the map file written while mapping: it cannot go with --no-checkpoints");
    if (!opt->push.session.empty() && opt->push.url.empty()) usage_error("--push-session goes with --push");
    if (opt->odometry && !opt->poses.empty()) usage_error("--odometry and --poses are two pose sources: give one");
    if (!opt->recording.pose_frame.empty() && (opt->odometry || !opt->poses.empty()))
      usage_error(fmt::format("--pose-frame and {} are two pose sources: give one", opt->odometry ? "--odometry" : "--poses"));
    if (!opt->tracking.loop_closure && !opt->odometry) usage_error("--no-loop-closure goes with --odometry");
    if (opt->no_checkpoints && cmd->count("--unload-radius") == 0) {  // no file to unload to: keep all
      opt->pipeline.unload_radius = 0;
      cmd->get_option("--unload-radius")->default_str("0");  // as the map records its options
    }
    if (opt->pipeline.unload_radius > 0 && opt->no_checkpoints)
      usage_error("--unload-radius needs the map file written while mapping: it cannot go with --no-checkpoints");
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("dataset", opt->dataset);
  io->input("--poses", opt->poses);
  io->input("--model", opt->model);
  io->input("--colour-basis", opt->colour_basis.file);
  io->input("--extrinsics", opt->recording.extrinsics);
  io->output("-o", opt->output, {}, /*lock=*/true);  // written while mapping: one run at a time
  cmd->callback([opt, cmd, io] {
    io->check();
    run(*opt, effective_config(*cmd));
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_map
