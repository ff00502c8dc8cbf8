#include "slamvdb/training/train_queries.hpp"
#include "slamvdb/core/mix64.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/eval/label_images.hpp"
#include "slamvdb/eval/pixel_scoring.hpp"

namespace slamvdb {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

QueryMatrix text_init(TextEncoder& text, const Ontology& ontology, int dim) {
  if (text.dim() != dim)
    throw Error(fmt::format("the text encoder '{}' gives {}-d embeddings but the image features are {}-d: they must "
                            "share one embedding space",
                            text.model_id(), text.dim(), dim));
  QueryMatrix q(ontology.num_classes(), dim);
  for (int k = 0; k < ontology.num_classes(); ++k) {
    const std::vector<float> v = text.encode(ontology.classes()[k].prompt);
    q.row(k) = Eigen::Map<const Eigen::RowVectorXf>(v.data(), dim);
  }
  return q;
}

QueryMatrix mean_init(const PixelSamples& train, const Ontology& ontology) {
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(ontology.num_classes(), train.dim());
  std::vector<float> row(train.dim());
  for (std::size_t i = 0; i < train.size(); ++i) {
    train.decode(i, 1, row.data());
    sum.row(train.targets()[i]) += Eigen::Map<const Eigen::RowVectorXf>(row.data(), train.dim()).cast<double>();
  }
  for (int k = 0; k < ontology.num_classes(); ++k)
    if (sum.row(k).squaredNorm() == 0)
      throw Error(fmt::format("class '{}' has no training pixel to start its query from (the class-mean "
                              "initialisation); give a text encoder or images that show it",
                              ontology.classes()[k].name));
  return sum.cast<float>();
}

// Accuracy and mIoU of `queries` on the validation pixels with the map's rule.
void validate_queries(const QuerySet& queries, const Ontology& ontology, const PixelSamples& val, EpochReport& r) {
  if (val.size() == 0) return;
  const QueryClassifier classifier(queries);
  const std::vector<int> to_class = ontology_classes_of(queries, ontology);
  ConfusionMatrix matrix = ontology_confusion_matrix(ontology);
  constexpr std::size_t kChunk = 8192;
  std::vector<float> x(kChunk * val.dim());
  std::vector<int> truth(kChunk);
  for (std::size_t first = 0; first < val.size(); first += kChunk) {
    const std::size_t n = std::min(kChunk, val.size() - first);
    val.decode(first, n, x.data());
    for (std::size_t i = 0; i < n; ++i) truth[i] = val.targets()[first + i];
    score_embeddings(x.data(), n, std::span(truth).first(n), classifier, to_class, matrix);
  }
  r.val_accuracy = matrix.accuracy();
  r.val_miou = matrix.mean_iou();
}

}  // namespace

void validate(const TrainQueriesOptions& o) {
  validate(o.trainer);
  if (o.pixels_per_image < 1) throw Error("pixels per image must be >= 1");
  if (!(o.val_fraction >= 0.0 && o.val_fraction < 1.0))
    throw Error(fmt::format("validation fraction must be in [0, 1), got {}", o.val_fraction));
}

std::size_t sample_memory_bytes(std::size_t images, std::size_t pixels_per_image, int dim) {
  return images * pixels_per_image * (static_cast<std::size_t>(dim) * 2 + 2);
}

QuerySet train_queries(std::span<const ImageRecord> images, FeatureSource& features, const Ontology& ontology,
                       TextEncoder* text, const TrainQueriesOptions& options, TrainQueriesReport& report,
                       const TrainingCallbacks& callbacks) {
  validate(options);
  if (options.init == QueryInit::kText && !text)
    throw Error("text initialisation needs a text encoder (--text-model, or SIMULATED features)");
  std::vector<const ImageRecord*> labelled;
  for (const auto& image : images)
    if (!image.labels.empty()) labelled.push_back(&image);
  report = {};
  report.without_labels = images.size() - labelled.size();
  if (labelled.empty()) throw Error(fmt::format("none of the {} images has a 2D label image", images.size()));
  const std::size_t n_val =
      options.val_fraction > 0 ? std::max<std::size_t>(1, std::lround(options.val_fraction * labelled.size())) : 0;
  if (n_val >= labelled.size())
    throw Error(fmt::format("{} labelled image(s) cannot be split into training and validation (validation fraction "
                            "{}); use more images or --val-fraction 0",
                            labelled.size(), options.val_fraction));
  report.train_images = labelled.size() - n_val;
  report.val_images = n_val;

  // Sample the pixels of every image once; the epochs reuse them.
  const Clock::time_point t0 = Clock::now();
  const LabelMapping targets_of = ontology.training_targets();
  std::optional<PixelSamples> train, val;
  for (std::size_t i = 0; i < labelled.size(); ++i) {
    const ImageRecord& image = *labelled[i];
    const FeatureMap map = features.features_for(image);
    const std::string where = image.labels.string();
    if (!train) {
      train.emplace(map.dim());
      val.emplace(map.dim());
      train->reserve(report.train_images * options.pixels_per_image);
      val->reserve(report.val_images * options.pixels_per_image);
    } else if (map.dim() != train->dim()) {
      throw Error(fmt::format("{}: {}-d features, the first image's were {}-d", where, map.dim(), train->dim()));
    }
    const std::vector<uint16_t> labels = read_labels_at(image.labels, map.width(), map.height());
    std::vector<int> targets(labels.size());
    for (std::size_t p = 0; p < labels.size(); ++p) {
      targets[p] = targets_of(labels[p]);
      if (targets[p] == LabelMapping::kUnknown)
        throw Error(fmt::format("{}: label id {} is not in ontology '{}' ({})", where, labels[p], ontology.name(),
                                ontology.source()));
    }
    const bool is_val = i >= report.train_images;
    const SampleCounts counts =
        sample_pixels(map, targets, options.pixels_per_image, is_val ? PixelSampling::kUniform : options.sampling,
                      mix64(options.trainer.seed ^ mix64(i)), is_val ? *val : *train);
    report.dropped_pixels += counts.bad;
    if (callbacks.image_progress) callbacks.image_progress(i + 1, labelled.size());
  }
  report.extract_seconds = seconds_since(t0);
  report.train_pixels = train->size();
  report.val_pixels = val->size();
  if (train->size() == 0) throw Error("the training images have no labelled pixel of any class");
  report.train_pixels_per_class.assign(ontology.num_classes(), 0);
  for (int16_t t : train->targets()) ++report.train_pixels_per_class[t];

  const bool use_text = options.init == QueryInit::kText || (options.init == QueryInit::kAuto && text);
  const QueryMatrix initial = use_text ? text_init(*text, ontology, train->dim()) : mean_init(*train, ontology);
  report.init = use_text ? fmt::format("text embeddings of the class names ({})", text->model_id())
                         : std::string("mean of each class's training pixels");

  const Clock::time_point t1 = Clock::now();
  QueryTrainer trainer(initial, options.trainer);
  const auto evaluate = [&](EpochReport& r) {
    if (val->size() == 0) return;
    r.val_loss = trainer.loss(*val);
    validate_queries(make_query_set(ontology, trainer.queries(), features.model_id()), ontology, *val, r);
  };
  EpochReport initial_report;
  evaluate(initial_report);
  report.epochs.push_back(initial_report);
  if (callbacks.epoch_done) callbacks.epoch_done(initial_report);
  for (int e = 1; e <= options.trainer.epochs; ++e) {
    const Clock::time_point te = Clock::now();
    EpochReport r;
    r.epoch = e;
    r.train_loss = trainer.train_epoch(*train, [&](std::size_t step, std::size_t steps) {
      if (callbacks.step_progress) callbacks.step_progress(e, step, steps);
    });
    evaluate(r);
    r.seconds = seconds_since(te);
    report.epochs.push_back(r);
    if (callbacks.epoch_done) callbacks.epoch_done(r);
  }
  report.train_seconds = seconds_since(t1);

  QuerySet q = make_query_set(ontology, trainer.queries(), features.model_id());
  auto& p = q.provenance;
  p.method = "train-queries";
  p.epochs = options.trainer.epochs;
  p.learning_rate = options.trainer.learning_rate;
  p.temperature = options.trainer.temperature;
  p.seed = options.trainer.seed;
  p.accuracy = report.epochs.back().val_accuracy;
  p.notes["ontology"] = ontology.name();
  p.notes["init"] = report.init;
  p.notes["sampling"] = options.sampling == PixelSampling::kUniform ? "uniform" : "class-balanced";
  p.notes["pixels_per_image"] = std::to_string(options.pixels_per_image);
  p.notes["batch_size"] = std::to_string(options.trainer.batch_size);
  p.notes["train_images"] = std::to_string(report.train_images);
  p.notes["val_images"] = std::to_string(report.val_images);
  p.notes["train_pixels"] = std::to_string(report.train_pixels);
  p.notes["val_pixels"] = std::to_string(report.val_pixels);
  if (const auto a = report.epochs.front().val_accuracy) p.notes["initial_val_accuracy"] = fmt::format("{:.6f}", *a);
  if (const auto m = report.epochs.back().val_miou) p.notes["val_miou"] = fmt::format("{:.6f}", *m);
  return q;
}

}  // namespace slamvdb
