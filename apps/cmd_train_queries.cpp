// `slamvdb train-queries`: trains one query vector per ontology class on labelled images
// (paper section 6.2.5) and writes them as a query set file with its provenance.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <optional>

#include "command_registry.hpp"
#include "feature_options.hpp"
#include "io_options.hpp"
#include "progress.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/ontology/ontology.hpp"
#if SLAMVDB_WITH_TRAINING
#include "slamvdb/training/train_queries.hpp"
#endif

namespace slamvdb::cli::cmd_train_queries {
namespace {

#if SLAMVDB_WITH_TRAINING
struct Options {
  std::string dataset, output, ontology = "rellis3d-coarse", sampling = "balanced", init = "auto";
  FeatureOptions features;
  TrainQueriesOptions train;
  double max_memory_gb = 8.0;
};

std::string pct(const std::optional<double>& v) { return v ? fmt::format("{:.2f}%", 100.0 * *v) : "-"; }

void run(Options opt) {
  // Everything that can be checked without reading images, before any work.
  check_feature_options(opt.features);
  opt.train.sampling = opt.sampling == "balanced" ? PixelSampling::kClassBalanced : PixelSampling::kUniform;
  opt.train.init = opt.init == "text" ? QueryInit::kText : opt.init == "mean" ? QueryInit::kClassMean : QueryInit::kAuto;
  try {
    validate(opt.train);
  } catch (const Error& e) {
    throw CLI::ValidationError("train-queries", e.what());
  }
  const Ontology ontology = Ontology::load_or_builtin(opt.ontology);
  const Sequence seq = read_sequence(opt.dataset);
  const std::vector<ImageRecord> images = select_labelled_images(seq, opt.features);
  const int dim_estimate = opt.features.features == "simulated" ? opt.features.dim : 512;
  const double gb = sample_memory_bytes(images.size(), opt.train.pixels_per_image, dim_estimate) / 1e9;
  if (gb > opt.max_memory_gb)
    throw CLI::ValidationError("--pixels-per-image",
                               fmt::format("{} images x {} pixels x {}-d take {:.1f} GB (> --max-memory {} GB); "
                                           "sample fewer pixels per image",
                                           images.size(), opt.train.pixels_per_image, dim_estimate, gb,
                                           opt.max_memory_gb));
  auto features = make_feature_source(opt.features, seq);
  std::unique_ptr<TextEncoder> text;
  if (opt.train.init != QueryInit::kClassMean) text = make_text_encoder(opt.features);
  fmt::print("train-queries: {} labelled images of {} ({}), ontology {} ({} classes), {} pixels per image ({}), "
             "samples ~{:.0f} MB\n",
             images.size(), seq.root.string(), seq.layout, escape_control(ontology.name()), ontology.num_classes(),
             opt.train.pixels_per_image, opt.sampling, gb * 1e3);
  std::fflush(stdout);

  std::optional<ProgressBar> image_bar, step_bar;
  TrainingCallbacks callbacks;
  const auto t0 = std::chrono::steady_clock::now();
  callbacks.image_progress = [&](std::size_t done, std::size_t total) {
    if (!image_bar) image_bar.emplace("features", total, "images");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    image_bar->update(done, fmt::format("{:.1f} images/s", s > 0 ? done / s : 0.0));
    if (done == total) image_bar->finish(fmt::format("{:.1f} images/s", s > 0 ? done / s : 0.0));
  };
  callbacks.step_progress = [&](int epoch, std::size_t step, std::size_t steps) {
    if (step == 1) step_bar.emplace(fmt::format("epoch {}/{}", epoch, opt.train.trainer.epochs), steps);
    step_bar->update(step, fmt::format("{} pixels/step", opt.train.trainer.batch_size));
    if (step == steps) step_bar->finish();
  };
  callbacks.epoch_done = [&](const EpochReport& r) {
    if (r.epoch == 0 && !r.val_loss) {
      fmt::print("no validation images (--val-fraction 0): only the training loss is reported\n");
    } else if (r.epoch == 0) {
      fmt::print("initial queries: validation loss {}, pixel accuracy {}, mIoU {}\n",
                 r.val_loss ? fmt::format("{:.4f}", *r.val_loss) : "-", pct(r.val_accuracy), pct(r.val_miou));
    } else {
      fmt::print("epoch {}/{}: train loss {:.4f}, validation loss {}, pixel accuracy {}, mIoU {} ({:.1f} s)\n", r.epoch,
                 opt.train.trainer.epochs, *r.train_loss, r.val_loss ? fmt::format("{:.4f}", *r.val_loss) : "-",
                 pct(r.val_accuracy), pct(r.val_miou), r.seconds);
    }
    std::fflush(stdout);
  };

  TrainQueriesReport report;
  QuerySet queries = train_queries(images, *features, ontology, text.get(), opt.train, report, callbacks);
  queries.provenance.notes["dataset"] = seq.root.string();
  queries.provenance.notes["features"] = opt.features.features;
  if (opt.features.features == "simulated") queries.provenance.notes["simulated"] = "true";
  save_query_set(opt.output, queries);
  fmt::print("{} training images ({} pixels), {} validation images ({} pixels), {} images without labels; "
             "initialised from the {}; features {:.1f} s, training {:.1f} s\n",
             report.train_images, report.train_pixels, report.val_images, report.val_pixels, report.without_labels,
             report.init, report.extract_seconds, report.train_seconds);
  if (report.dropped_pixels) fmt::print("{} sampled pixels had zero or non-finite features and were dropped\n", report.dropped_pixels);
  fmt::print("query set ({} classes, {}-d, model {}) saved to {}\n", queries.size(), queries.dim(),
             escape_control(queries.model_id), opt.output);
}
#endif

void add(CLI::App& root) {
#if SLAMVDB_WITH_TRAINING
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "train-queries",
      "Train one query vector per ontology class on labelled images (paper 6.2.5): LSeg's loss (softmax "
      "cross-entropy over temperature-scaled cosines) optimised with Adam; initialised from the text embeddings of "
      "the class names (or the class means without a text encoder). Images are split by time: the last "
      "--val-fraction validates. Writes a query set file (JSON) with its provenance");
  cmd->add_option("dataset", opt->dataset, "Sequence directory (RELLIS-3D or KITTI layout) with 2D label images")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("-o,--output", opt->output, "Query set file to write (.json)")->required();
  cmd->add_option("--ontology", opt->ontology, "Ontology YAML file, or a built-in one: rellis3d-coarse, rellis3d-fine")
      ->capture_default_str();
  auto& t = opt->train.trainer;
  cmd->add_option("--epochs", t.epochs, "Passes over the training pixels")
      ->capture_default_str()
      ->check(integer_range(0, 1'000'000));
  cmd->add_option("--batch-size", t.batch_size, "Pixels per optimiser step")
      ->capture_default_str()
      ->check(integer_range(1, bounds::kMaxCount));
  cmd->add_option("--lr", t.learning_rate, "Adam learning rate")->capture_default_str()->check(kPositive);
  cmd->add_option("--temperature", t.temperature, "Softmax temperature: logits = cosine / T")
      ->capture_default_str()
      ->check(kPositive);
  cmd->add_option("--seed", t.seed, "Seed for pixel sampling and shuffling (same seed, same vectors)")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_option("--val-fraction", opt->train.val_fraction, "Share of the images (the last ones) used for validation")
      ->capture_default_str()
      ->check(finite_range(0.0, 0.95));
  cmd->add_option("--pixels-per-image", opt->train.pixels_per_image, "Labelled pixels sampled per image")
      ->capture_default_str()
      ->check(integer_range(1, bounds::kMaxCount));
  cmd->add_option("--sampling", opt->sampling,
                  "Training pixel sampling: 'balanced' (even share per class in each image: more pixels of rare "
                  "classes, better rare-class recall) or 'uniform' (the paper's loss in expectation)")
      ->capture_default_str()
      ->check(CLI::IsMember({"uniform", "balanced"}));
  cmd->add_option("--init", opt->init,
                  "Initial queries: 'text' (class names through the text encoder), 'mean' (class means of the "
                  "training pixels), 'auto' (text when a text encoder is available)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "text", "mean"}));
  cmd->add_option("--max-memory", opt->max_memory_gb, "Refuse to start if the sampled pixels would take more GB")
      ->capture_default_str()
      ->check(kPositive);
  add_feature_options(cmd, opt->features, true);
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("dataset", opt->dataset);
  io->input("--ontology", opt->ontology);
  add_feature_inputs(*io, opt->features);
  io->output("-o", opt->output);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
#else
  root.add_subcommand("train-queries", "Unavailable: this slamvdb was built without libtorch (SLAMVDB_WITH_TORCH=OFF)")
      ->callback([] { throw Error("train-queries needs libtorch: rebuild with -DSLAMVDB_WITH_TORCH=ON"); });
#endif
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_train_queries
