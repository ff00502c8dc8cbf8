// `slamvdb eval-images`: the per-image baseline. Classifies every pixel of every labelled image
// with a query set (the map's rule, void -> second best) and scores it against the 2D labels, so
// the gain of fusing views into voxels can be measured against it.
#include <fmt/format.h>

#include <chrono>
#include <optional>

#include "command_registry.hpp"
#include "feature_options.hpp"
#include "io_options.hpp"
#include "progress.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/eval/confusion_png.hpp"
#include "slamvdb/eval/image_baseline.hpp"
#include "slamvdb/io/sequence_reader.hpp"

namespace slamvdb::cli::cmd_eval_images {
namespace {

struct Options {
  std::string dataset, queries, ontology = "rellis3d-coarse", markdown, json, csv, png;
  FeatureOptions features;
  bool no_void_rule = false, ignore_model_id = false;
};

void run(const Options& opt) {
  check_feature_options(opt.features);
  const QuerySet queries = load_query_set(opt.queries);
  const Ontology ontology = Ontology::load_or_builtin(opt.ontology);
  ontology_classes_of(queries, ontology);  // fail before reading images
  const Sequence seq = read_sequence(opt.dataset);
  const std::vector<ImageRecord> images = select_labelled_images(seq, opt.features);
  auto features = make_feature_source(opt.features, seq);

  ImageBaselineOptions options;
  options.classify.void_to_second_best = !opt.no_void_rule;
  options.model_check = opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch;
  std::optional<ProgressBar> bar;
  const auto t0 = std::chrono::steady_clock::now();
  const ImageBaselineResult r =
      evaluate_image_baseline(images, *features, queries, ontology, options, [&](std::size_t done, std::size_t total) {
        if (!bar) bar.emplace("images", total, "images");
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        bar->update(done, fmt::format("{:.1f} images/s", s > 0 ? done / s : 0.0));
      });
  if (bar) bar->finish();
  const MetricsReport report = r.matrix.report();
  fmt::print("per-image baseline: {} images, {} labelled pixels at the feature resolution ({} unlabelled), queries "
             "{} ({}), void -> second best {}\n\n{}",
             r.images, r.pixels, r.unlabelled_pixels, opt.queries, escape_control(queries.model_id),
             opt.no_void_rule ? "off" : "on", to_markdown(report));
  if (!opt.markdown.empty()) write_output_file(opt.markdown, to_markdown(report));
  if (!opt.json.empty()) write_output_file(opt.json, to_json(report));
  if (!opt.csv.empty()) write_output_file(opt.csv, to_csv(report));
  if (!opt.png.empty())
    write_confusion_png(opt.png, r.matrix, fmt::format("per-image baseline, {} images", r.images));
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "eval-images",
      "Per-image baseline: classify every pixel of the labelled images directly with a query set (same rule as the "
      "map: void takes the second-best class) and score it against the 2D labels at the feature resolution (void "
      "ignored). Prints the paper's Table 6.1 form");
  cmd->add_option("dataset", opt->dataset, "Sequence directory with 2D label images")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--queries", opt->queries, "Query set file (from train-queries or import-queries)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--ontology", opt->ontology, "Ontology file or built-in name")->capture_default_str();
  cmd->add_option("-o,--output", opt->markdown, "Write the markdown table here");
  cmd->add_option("--json", opt->json, "Write the scores as JSON");
  cmd->add_option("--csv", opt->csv, "Write the scores as CSV");
  cmd->add_option("--png", opt->png, "Write the confusion matrix as a PNG");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "Let void classes win (the paper's rule is on by default)");
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "Accept queries whose model id differs from the features' (the dimension is still checked)");
  add_feature_options(cmd, opt->features, false);
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("dataset", opt->dataset);
  io->input("--queries", opt->queries);
  io->input("--ontology", opt->ontology);
  add_feature_inputs(*io, opt->features);
  io->output("-o", opt->markdown);
  io->output("--json", opt->json);
  io->output("--csv", opt->csv);
  io->output("--png", opt->png);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_eval_images
