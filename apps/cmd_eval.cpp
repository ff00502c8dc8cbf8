// `slamvdb eval`: the paper's evaluation of a semantic map against a labelled sequence (Table 6.1):
// hit rate and voxel-wise recall / precision / IoU, with the per-image baseline beside it.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <optional>

#include "command_registry.hpp"
#include "feature_options.hpp"
#include "io_options.hpp"
#include "progress.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/eval/confusion_png.hpp"
#include "slamvdb/eval/coverage_png.hpp"
#include "slamvdb/eval/image_baseline.hpp"
#include "slamvdb/eval/map_evaluation.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_eval {
namespace {

struct Options {
  std::string map, dataset, queries, ontology = "rellis3d-coarse", markdown, json, csv, png, coverage_png, part = "0:1";
  FeatureOptions features;
  bool baseline = false, no_void_rule = false, ignore_model_id = false;
};

// --part A:B: the time fraction [A, B] of the drive (0:1 all of it; 0.5:1 its second half).
std::pair<double, double> parse_part(const std::string& text) {
  const auto colon = text.find(':');
  double a = -1, b = -1;
  try {
    if (colon != std::string::npos) a = std::stod(text.substr(0, colon)), b = std::stod(text.substr(colon + 1));
  } catch (const std::exception&) {
  }
  if (!(a >= 0 && b <= 1 && a < b))
    throw CLI::ValidationError("--part", fmt::format("'{}' is not FROM:TO with 0 <= FROM < TO <= 1", text));
  return {a, b};
}

struct Timer {
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }
};

void run(Options opt) {
  check_feature_options(opt.features);
  const auto [from, to] = parse_part(opt.part);
  const QuerySet queries = load_query_set(opt.queries);
  const Ontology ontology = Ontology::load_or_builtin(opt.ontology);
  ontology_classes_of(queries, ontology);  // fail before any long work
  const SemanticMap map = load_map(opt.map);
  const Sequence seq = read_sequence(opt.dataset);
  if (seq.poses.empty()) throw Error(fmt::format("{} has no ground-truth poses (poses.txt)", seq.root.string()));
  if (seq.scans.empty()) throw Error(fmt::format("{} has no scans", seq.root.string()));
  const double t0 = seq.scans.front().stamp, t1 = seq.scans.back().stamp;
  const double begin = t0 + from * (t1 - t0), end = t0 + to * (t1 - t0);

  std::vector<GroundTruthScan> scans;
  std::size_t without_labels = 0, without_pose = 0;
  for (const ScanRecord& rec : seq.scans) {
    if (rec.stamp < begin || rec.stamp > end) continue;
    if (rec.labels.empty()) {
      ++without_labels;
      continue;
    }
    const auto pose = seq.poses.at(rec.stamp);
    if (!pose) {
      ++without_pose;
      continue;
    }
    scans.push_back({*pose, [rec] { return read_scan(rec); }, rec.points.filename().string()});
  }
  if (scans.empty()) throw Error(fmt::format("no labelled scan with a pose in part {} of {}", opt.part, seq.root.string()));

  MapEvaluationOptions options;
  options.classify.void_to_second_best = !opt.no_void_rule;
  options.model_check = opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch;
  std::optional<ProgressBar> bar;
  const Timer timer;
  const MapEvaluation r = evaluate_map(map, scans, queries, ontology, options, [&](std::size_t done, std::size_t total) {
    if (!bar) bar.emplace("eval", total, "scans");
    bar->update(done, fmt::format("{:.0f} scans/s", done / std::max(timer.seconds(), 1e-9)));
  });
  if (bar) bar->finish();
  fmt::print("map {} against {} (part {}): {} scans ({} without labels, {} without a pose), {} points: {} counted, "
             "{} void, {} unlabelled, {} outside every non-empty voxel; {} non-empty voxels, {} hold labelled points; "
             "void -> second best {}\n\n{}",
             opt.map, seq.root.string(), opt.part, r.scans, without_labels, without_pose, r.points_total,
             r.points.scored(), r.points_void, r.points_unlabelled, r.points_outside, r.map_cells, r.cells_with_points,
             opt.no_void_rule ? "off" : "on", to_markdown(r.report));

  nlohmann::json json = nlohmann::json::parse(to_json(r.report));
  json["points"] = {{"total", r.points_total}, {"counted", r.points.scored()}, {"void", r.points_void},
                    {"unlabelled", r.points_unlabelled}, {"outside", r.points_outside}};
  json["voxels"] = {{"non_empty", r.map_cells}, {"with_points", r.cells_with_points}};
  json["part"] = {from, to};
  std::string markdown = to_markdown(r.report);
  // Voxels ranked by how sure the map is of their class (query/class_confidence.hpp).
  const std::vector<CoveragePoint> coverage = accuracy_coverage(r);
  fmt::print("\naccuracy of the most confident voxels:\n\n{}", coverage_markdown(coverage));
  markdown += "\nAccuracy of the most confident voxels:\n\n" + coverage_markdown(coverage);
  json["accuracy_coverage"] = nlohmann::json::parse(coverage_json(coverage));
  // How the confidence compares with the accuracy it predicts.
  const std::vector<CalibrationBin> calibration = calibration_table(r);
  fmt::print("\ncalibration (voxels binned by confidence):\n\n{}", calibration_markdown(calibration));
  markdown += "\nCalibration (voxels binned by confidence):\n\n" + calibration_markdown(calibration);
  json["calibration"] = nlohmann::json::parse(calibration_json(calibration));
  if (opt.baseline) {
    std::vector<ImageRecord> images;
    for (const ImageRecord& img : select_labelled_images(seq, opt.features))
      if (img.stamp >= begin && img.stamp <= end) images.push_back(img);
    auto source = make_feature_source(opt.features, seq);
    // The baseline should see the images through the encoder the map was made with: the model id
    // (checked against the queries) names the embedding space only, not the failure modes.
    if (!map.info().features.empty() && map.info().features != source->description())
      spdlog::warn("--baseline: the map was made with the encoder settings '{}', the baseline runs with '{}' (give the "
                   "map's --sim-encoder / --sim-* options to compare like with like)",
                   escape_control(map.info().features), escape_control(source->description()));
    ImageBaselineOptions baseline_options;
    baseline_options.classify = options.classify;
    baseline_options.model_check = options.model_check;
    std::optional<ProgressBar> ibar;
    const Timer itimer;
    const ImageBaselineResult b = evaluate_image_baseline(
        images, *source, queries, ontology, baseline_options, [&](std::size_t done, std::size_t total) {
          if (!ibar) ibar.emplace("baseline", total, "images");
          ibar->update(done, fmt::format("{:.1f} images/s", done / std::max(itimer.seconds(), 1e-9)));
        });
    if (ibar) ibar->finish();
    const MetricsReport br = b.matrix.report();
    fmt::print("\nper-image baseline (the same queries on the pixels of {} images, scored against the 2D labels):\n\n{}",
               b.images, to_markdown(br));
    auto pct = [](const std::optional<double>& v) { return v ? fmt::format("{:.2f}%", 100 * *v) : std::string("n/a"); };
    fmt::print("\nfused map vs per-image baseline: accuracy {} vs {}, mIoU {} vs {}\n", pct(r.report.accuracy),
               pct(br.accuracy), pct(r.report.miou), pct(br.miou));
    json["baseline"] = nlohmann::json::parse(to_json(br));
    json["baseline"]["images"] = b.images;
    markdown += "\nPer-image baseline:\n\n" + to_markdown(br);
  }
  if (!opt.markdown.empty()) write_output_file(opt.markdown, markdown);
  if (!opt.json.empty()) write_output_file(opt.json, json.dump(2) + "\n");
  if (!opt.csv.empty()) write_output_file(opt.csv, to_csv(r.report));
  if (!opt.png.empty())
    write_confusion_png(opt.png, r.voxels, fmt::format("voxel-wise labelling, {} voxels", r.voxels.scored()));
  if (!opt.coverage_png.empty())
    write_coverage_png(opt.coverage_png,
                       {{map.info().fusion.empty() ? std::string("map") : "map (" + map.info().fusion + " fusion)",
                         accuracy_coverage(r, coverage_plot_fractions())}},
                       fmt::format("accuracy of the most confident voxels, {} voxels", r.scored_voxels.size()));
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "eval",
      "Evaluate a semantic map against a labelled sequence as the paper does (Table 6.1): hit rate (labelled LiDAR "
      "points in a voxel of their class) and voxel-wise recall, precision and IoU (each non-empty voxel labelled by "
      "the majority of its points), void ignored; optionally beside the per-image baseline");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required()->check(CLI::ExistingFile);
  cmd->add_option("dataset", opt->dataset, "Labelled sequence with ground-truth poses (RELLIS-3D or KITTI layout)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--queries", opt->queries, "Query set file (train-queries / import-queries)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--ontology", opt->ontology, "Ontology file or built-in name")->capture_default_str();
  cmd->add_option("--part", opt->part, "Evaluate only the time fraction FROM:TO of the drive (e.g. 0.5:1)")
      ->capture_default_str();
  cmd->add_option("-o,--output", opt->markdown, "Write the markdown table here");
  cmd->add_option("--json", opt->json, "Write the scores as JSON (top level: accuracy, hit_rate, miou, classes)");
  cmd->add_option("--csv", opt->csv, "Write the scores as CSV");
  cmd->add_option("--png", opt->png, "Write the voxel-wise confusion matrix as a PNG");
  cmd->add_option("--coverage-png", opt->coverage_png,
                  "Write the accuracy-coverage curve (accuracy of the most confident x % of the voxels) as a PNG plot");
  cmd->add_flag("--baseline", opt->baseline,
                "Also classify the pixels of the labelled images in the same part directly (the per-image baseline)");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "Let void classes win (the paper's rule is on by default)");
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "Accept queries whose model id differs from the map's (the dimension is still checked)");
  add_feature_options(cmd, opt->features, false);
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("map", opt->map);
  io->input("dataset", opt->dataset);
  io->input("--queries", opt->queries);
  io->input("--ontology", opt->ontology);
  add_feature_inputs(*io, opt->features);
  io->output("-o", opt->markdown);
  io->output("--json", opt->json);
  io->output("--csv", opt->csv);
  io->output("--png", opt->png);
  io->output("--coverage-png", opt->coverage_png);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_eval
