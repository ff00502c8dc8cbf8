// `slamvdb demo`: the main job on built-in defaults, start to finish on a SIMULATED drive: generate
// (or reuse) the sequence, build the map, train query vectors on images from the first half of the
// drive, evaluate on the second half against the baselines (which also measures the confidence
// below which voxels are uncertain), classify the map, and write the pictures and files a user
// looks at first. The drive is also written as a ROS 2 MCAP recording (drive.mcap, to open in
// Foxglove), and its scans are read back through the recording input `map` uses and checked
// against the folder's.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>

#include "colour_basis_option.hpp"
#include "command_registry.hpp"
#include "option_checks.hpp"
#include "io_options.hpp"
#include "demo_outputs.hpp"
#include "progress.hpp"
#include "slamvdb/eval/confusion_png.hpp"
#include "slamvdb/eval/coverage_png.hpp"
#include "slamvdb/eval/image_baseline.hpp"
#include "slamvdb/eval/map_evaluation.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/map_export.hpp"
#include "slamvdb/io/rellis_reader.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/sensors/mcap_export.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#if SLAMVDB_WITH_TRAINING  // the demo trains query vectors (libtorch); without it there is no demo command
#include "slamvdb/training/train_queries.hpp"

namespace slamvdb::cli::cmd_demo {
namespace {
namespace fs = std::filesystem;

struct Options {
  std::string out = "out";
  double length = 320.0;
  uint64_t seed = 1;
  bool fresh = false;
};

class Step {
 public:
  explicit Step(std::string what) : what_(std::move(what)) { fmt::print("\n== {}\n", what_); }
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count(); }

 private:
  std::string what_;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
};

// A progress callback that creates its bar on the first call.
auto progress_bar(std::optional<ProgressBar>& bar, const char* label, const char* unit) {
  return [&bar, label, unit, t0 = std::chrono::steady_clock::now()](std::size_t done, std::size_t total) {
    if (!bar) bar.emplace(label, total);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    bar->update(done, fmt::format("{:.1f} {}/s", s > 0 ? done / s : 0.0, unit));
  };
}

void run(const Options& opt) {
  const fs::path out = opt.out;
  fs::create_directories(out);
  const fs::path seq_dir = out / "sequence";
  std::vector<std::pair<std::string, double>> timings;
  const auto t_all = std::chrono::steady_clock::now();

  // 1. The SIMULATED sequence (reused when it is there and was made with the same settings).
  {
    Step step("SIMULATED sequence");
    synth::SynthConfig config;
    config.seed = opt.seed;
    config.length_m = opt.length;
    bool reuse = false;
    if (!opt.fresh && fs::exists(seq_dir / "synth.json")) {
      try {
        const auto j = nlohmann::json::parse(std::ifstream(seq_dir / "synth.json"));
        // A sequence written before synth wrote the SIMULATED view geometry cannot feed the
        // realistic encoder's view-dependent errors: it is made again.
        reuse = j.at("seed").get<uint64_t>() == opt.seed && j.at("parameters").at("length_m").get<double>() == opt.length &&
                fs::is_directory(seq_dir / kRellisSimViewDir);
        read_sequence(seq_dir);  // complete and readable
      } catch (const std::exception&) {
        reuse = false;
      }
    }
    if (reuse) {
      fmt::print("reusing {} (seed {}, {} m)\n", seq_dir.string(), opt.seed, opt.length);
    } else {
      std::optional<ProgressBar> bar;
      const auto summary = synth::write_synthetic_sequence(config, seq_dir, true, progress_bar(bar, "synth", "frames"));
      if (bar) bar->finish();
      fmt::print("{} scans, {} images, {:.0f} m -> {}\n", summary.scans, summary.images, summary.path_length_m,
                 seq_dir.string());
    }
    timings.emplace_back("sequence", step.seconds());
  }
  const Sequence seq = read_sequence(seq_dir);

  // 1b. The drive as a ROS 2 MCAP recording (kept while the sequence is reused), and its scans
  // read back through the recording path. The map below is made from the folder: the recording
  // carries no SIMULATED view geometry, which the realistic encoder's errors depend on.
  {
    Step step("ROS 2 MCAP recording of the drive");
    const fs::path mcap = out / "drive.mcap";
    std::error_code ec;
    if (!fs::exists(mcap, ec) || fs::last_write_time(mcap, ec) < fs::last_write_time(seq_dir / "synth.json", ec)) {
      std::optional<ProgressBar> bar;
      const McapExportSummary s = write_sequence_mcap(seq, mcap, {}, progress_bar(bar, "mcap", "frames"));
      if (bar) bar->finish();
      fmt::print("{:.0f} MB in {:.1f} s -> {} (open it in Foxglove; `slamvdb map {}` maps it like the folder)\n",
                 static_cast<double>(s.bytes) / 1e6, step.seconds(), mcap.string(), mcap.string());
    }
    fmt::print("recording check: its {} scans, read back as `map` reads a recording, are the folder's, bit for bit\n",
               compare_recording_scans(seq, mcap));
    timings.emplace_back("recording", step.seconds());
  }

  // 2. The map (simulated features, default settings: the realistic encoder, the default fusion
  // rule). The encoder keeps its default seed whatever the drive's: its seed is part of the model
  // id (the embedding space), which `query` and `classify` must match with their defaults.
  const SimulatedEncoderConfig sim;
  const FusionWeighting map_rule = PipelineOptions{}.fusion.weighting;
  fmt::print("features are SIMULATED: {}\n", sim.describe());
  {
    Step step("map");
    EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(sim), EncoderFeatureSource::Input::kLabels);
    PipelineReport report;
    std::optional<ProgressBar> bar;
    SemanticMap map = build_map(seq, &source, PipelineOptions{}, report, progress_bar(bar, "map", "scans"));
    if (bar) bar->finish();
    fmt::print("{}\n", report.summary());
    record_colour_basis(map, {});
    save_map(out / "map.svdb", map);
    fmt::print("map: {} submaps, {} semantic voxels in {} index cells -> {}\n", map.num_submaps(),
               map.num_semantic_voxels(), map.num_index_cells(), (out / "map.svdb").string());
    timings.emplace_back("map", step.seconds());
  }
  const SemanticMap map = load_map(out / "map.svdb");

  // The drive's two halves by time: queries are trained on the first, the map is scored on the second.
  const double t0 = seq.scans.front().stamp, t1 = seq.scans.back().stamp, t_mid = 0.5 * (t0 + t1);
  std::vector<ImageRecord> first_half, second_half;
  for (const ImageRecord& img : seq.images) (img.stamp < t_mid ? first_half : second_half).push_back(img);

  // 3. Query vectors.
  const Ontology ontology = Ontology::builtin("rellis3d-coarse");
  QuerySet queries;
  {
    Step step("query vectors (trained on the first half of the drive)");
    EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(sim), EncoderFeatureSource::Input::kLabels);
    SimulatedTextEncoder text(sim);
    TrainQueriesReport report;
    std::optional<ProgressBar> bar;
    TrainingCallbacks callbacks;
    callbacks.image_progress = progress_bar(bar, "features", "images");
    callbacks.epoch_done = [](const EpochReport& e) {
      if (e.val_accuracy)
        fmt::print("epoch {}: validation pixel accuracy {:.2f}%\n", e.epoch, 100 * *e.val_accuracy);
    };
    queries = train_queries(first_half, source, ontology, &text, TrainQueriesOptions{}, report, callbacks);
    if (bar) bar->finish();
    save_query_set(out / "queries.json", queries);
    fmt::print("{} classes from {} training images -> {}\n", queries.size(), report.train_images,
               (out / "queries.json").string());
    timings.emplace_back("training", step.seconds());
  }

  // 4. Evaluation on the second half, beside the per-image baseline. It also measures the
  // confidence threshold the pictures use: the least confident tenth of the scored voxels is
  // uncertain (hatched, unknown to the planner).
  float min_confidence = 0.f;
  {
    Step step("evaluation (second half of the drive)");
    std::vector<GroundTruthScan> scans;
    for (const ScanRecord& rec : seq.scans)
      if (rec.stamp >= t_mid && !rec.labels.empty())
        if (const auto pose = seq.poses.at(rec.stamp))
          scans.push_back({*pose, [rec] { return read_scan(rec); }, rec.points.filename().string()});
    std::optional<ProgressBar> bar;
    const MapEvaluation e = evaluate_map(map, scans, queries, ontology, {}, progress_bar(bar, "eval", "scans"));
    if (bar) bar->finish();
    EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(sim), EncoderFeatureSource::Input::kLabels);
    std::optional<ProgressBar> ibar;
    const ImageBaselineResult b =
        evaluate_image_baseline(second_half, source, queries, ontology, {}, progress_bar(ibar, "baseline", "images"));
    if (ibar) ibar->finish();
    const MetricsReport br = b.matrix.report();
    // The same drive mapped with the other fusion rule and with one view per voxel (the
    // single-view baseline), scored with the same voxel protocol: what fusion and its weighting add.
    // Each costs one more mapping pass (about the map step's time again).
    const auto evaluate_rule = [&](FusionWeighting rule) {
      EncoderFeatureSource rule_source(std::make_unique<SimulatedDenseEncoder>(sim), EncoderFeatureSource::Input::kLabels);
      PipelineOptions options;
      options.fusion.weighting = rule;
      options.map.semantic.single_view = rule == FusionWeighting::kSingleView;
      PipelineReport report;
      const SemanticMap rule_map = build_map(seq, &rule_source, options, report, {});
      return evaluate_map(rule_map, scans, queries, ontology, {});
    };
    const FusionWeighting other_rule =
        map_rule == FusionWeighting::kPaper ? FusionWeighting::kQuality : FusionWeighting::kPaper;
    const auto rule_title = [](FusionWeighting rule) {
      return rule == FusionWeighting::kPaper ? std::string("paper's running mean (Eq. 6.1)")
                                             : std::string("quality-weighted fusion");
    };
    fmt::print("mapping again with the {} rule and with one view per voxel (baselines)\n", to_string(other_rule));
    const MapEvaluation other = evaluate_rule(other_rule);
    const MapEvaluation single = evaluate_rule(FusionWeighting::kSingleView);
    const std::vector<CoveragePoint> coverage = accuracy_coverage(e);
    const std::vector<CalibrationBin> calibration = calibration_table(e);
    min_confidence = accuracy_coverage(e, {0.9}).at(0).min_confidence;
    const std::vector<CoveragePoint> confident = accuracy_coverage(e, {0.9, 1.0});
    const double rest = (confident[1].accuracy * confident[1].voxels - confident[0].accuracy * confident[0].voxels) /
                        std::max<double>(1.0, static_cast<double>(confident[1].voxels - confident[0].voxels));
    write_coverage_png(out / "coverage.png",
                       {{fmt::format("{} (map.svdb)", to_string(map_rule)), accuracy_coverage(e, coverage_plot_fractions())},
                        {std::string(to_string(other_rule)), accuracy_coverage(other, coverage_plot_fractions())}},
                       "SIMULATED drive: accuracy of the most confident voxels");
    const std::string summary = comparison_markdown(
        {{fmt::format("map, {} (map.svdb)", rule_title(map_rule)), "voxels", e.voxels},
         {fmt::format("map, {}", rule_title(other_rule)), "voxels", other.voxels},
         {"single-view voxel baseline (nearest view per voxel)", "voxels", single.voxels},
         {"per-image baseline (pixels of each image on its own)", "pixels", b.matrix}});
    const std::string text = fmt::format(
        "# Terrain segmentation accuracy (SIMULATED drive, seed {}, second half)\n\n"
        "Features are SIMULATED by the realistic encoder: {}\n\n{}\n"
        "The map and its two voxel baselines are scored voxel by voxel against the majority label of the LiDAR "
        "points in each voxel ({} scans); the per-image baseline is scored pixel by pixel at feature resolution "
        "against the label images ({} images): the two measures differ (voxels weigh each place once, pixels "
        "weigh near surfaces more), so fusion's gain is read against the single-view voxel baseline, and the "
        "per-image baseline shows what one image alone gets in its own measure.\n\n"
        "## Map ({}, map.svdb), paper Table 6.1 form, void ignored\n\n{}\n"
        "## Map, {}\n\n{}\n## Single-view voxel baseline\n\n{}\n## Per-image baseline\n\n{}\n"
        "## Accuracy against coverage (map, {})\n\nVoxels ranked by confidence (the margin between "
        "the best and second-best class, damped for voxels seen in few views: voxel_confidence; "
        "coverage.png plots both rules):\n\n{}\n"
        "## Calibration (map)\n\n{}\n"
        "The pictures (classes.png, nav.png) hatch the least confident tenth of the voxels as uncertain "
        "(confidence < {:.3f}, unknown to the planner in nav.pgm): they are {:.1f} % accurate, the rest {:.1f} %.\n",
        opt.seed, sim.describe(), summary, e.scans, b.images, rule_title(map_rule), to_markdown(e.report),
        rule_title(other_rule), to_markdown(other.report), to_markdown(single.report), to_markdown(br),
        rule_title(map_rule), coverage_markdown(coverage), calibration_markdown(calibration), min_confidence,
        100 * rest, 100 * confident[0].accuracy);
    fmt::print("\n{}", text);
    write_output_file(out / "eval.md", text);
    nlohmann::json json = nlohmann::json::parse(to_json(e.report));
    json["simulated_encoder"] = sim.describe();
    json["fusion"] = std::string(to_string(map_rule));  // the rule map.svdb was fused with
    json["other_rule"] = nlohmann::json::parse(to_json(other.report));
    json["other_rule"]["fusion"] = std::string(to_string(other_rule));
    json["single_view_baseline"] = nlohmann::json::parse(to_json(single.report));
    json["baseline"] = nlohmann::json::parse(to_json(br));
    json["accuracy_coverage"] = nlohmann::json::parse(coverage_json(coverage));
    json["calibration"] = nlohmann::json::parse(calibration_json(calibration));
    json["min_confidence"] = min_confidence;
    write_output_file(out / "eval.json", json.dump(2) + "\n");
    write_confusion_png(out / "confusion.png", e.voxels, fmt::format("voxel-wise labelling, {} voxels", e.voxels.scored()));
    timings.emplace_back("evaluation", step.seconds());
  }

  // 5. Classification of the whole map, the least confident voxels uncertain.
  {
    Step step("classification");
    std::vector<ClassifiedCell> cells = classify_map(map, queries);
    sort_by_cell(cells);
    write_classified_csv(out / "classes.csv", cells, queries, min_confidence);
    std::vector<Eigen::Vector2d> path;
    for (const Pose& T : seq.poses.poses()) path.push_back(T.translation().head<2>());
    write_class_outputs(out, map, cells, queries, path, min_confidence);
    timings.emplace_back("classification", step.seconds());
  }

  // 6. A text query, and the whole map as a point cloud.
  {
    Step step("query and export");
    write_query_outputs(out, map, "grass", sim);
    write_ply(out / "map.ply", colour_by_pca(map), PlyEncoding::kBinaryLittleEndian);
    timings.emplace_back("query and export", step.seconds());
  }

  fmt::print("\n== done in {:.1f} s (", std::chrono::duration<double>(std::chrono::steady_clock::now() - t_all).count());
  for (std::size_t i = 0; i < timings.size(); ++i)
    fmt::print("{}{} {:.1f} s", i ? ", " : "", timings[i].first, timings[i].second);
  fmt::print(")\n");
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(out))
    if (entry.is_regular_file()) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  fmt::print("outputs (classes.png: terrain from above; nav.*: navigation grid for Nav2; query_grass.png: heat map; "
             "map.html: 3D view; eval.md: the paper's table; coverage.png: accuracy of the most confident voxels; "
             "drive.mcap: the drive as a ROS 2 recording, for Foxglove):\n");
  for (const fs::path& f : files) fmt::print("  {}\n", f.string());
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "demo",
      "The main job on built-in defaults, on a SIMULATED drive: generate (or reuse) the sequence, map it, train query "
      "vectors on the first half, classify the map, evaluate it on the second half (paper Table 6.1) beside the "
      "paper's fusion rule, a single-view voxel baseline and the per-image baseline, and write the pictures (class map, navigation grid, confusion matrix, a query heat map)");
  cmd->add_option("out,-o,--output", opt->out, "Output folder")->capture_default_str();
  cmd->add_option("--length", opt->length, "Length of the simulated drive (m)")->capture_default_str()->check(finite_range(20.0, 10000.0));
  cmd->add_option("--seed", opt->seed, "Seed of the simulated drive")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_flag("--fresh", opt->fresh, "Generate the sequence again even if the output folder has one");
  auto io = std::make_shared<IoOptions>(cmd);
  io->output_folder("-o", opt->out, {}, /*lock=*/true);  // filled for minutes: one run at a time
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_demo
#endif  // SLAMVDB_WITH_TRAINING
