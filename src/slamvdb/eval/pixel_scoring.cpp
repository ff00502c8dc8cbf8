#include "slamvdb/eval/pixel_scoring.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

ConfusionMatrix ontology_confusion_matrix(const Ontology& ontology) {
  return ConfusionMatrix(ontology.class_names(), ontology.void_classes());
}

void score_embeddings(const float* embeddings, std::size_t rows, std::span<const int> truth,
                      const QueryClassifier& classifier, std::span<const int> query_to_class,
                      ConfusionMatrix& matrix) {
  if (truth.size() != rows) throw Error(fmt::format("{} ground-truth labels for {} embeddings", truth.size(), rows));
  if (static_cast<int>(query_to_class.size()) != classifier.num_classes())
    throw Error(fmt::format("{} query classes mapped, the classifier has {}", query_to_class.size(),
                            classifier.num_classes()));
  std::vector<QueryMatch> matches(rows);
  classifier.classify(embeddings, rows, matches.data());
  for (std::size_t i = 0; i < rows; ++i) {
    if (truth[i] < 0) continue;
    const int predicted =
        matches[i].class_index == kNoClass ? ConfusionMatrix::kNoPrediction : query_to_class[matches[i].class_index];
    matrix.add(truth[i], predicted);
  }
}

PixelCounts score_feature_map(const FeatureMap& map, std::span<const uint16_t> labels,
                              const LabelMapping& ground_truth, const QueryClassifier& classifier,
                              std::span<const int> query_to_class, ConfusionMatrix& matrix, std::string_view where) {
  // The classifier reads fp32 rows: an fp16 map is widened once (exactly).
  const bool half = map.precision() == EmbeddingPrecision::kFloat16;
  const FeatureMap widened = half ? map.converted(EmbeddingPrecision::kFloat32) : FeatureMap();
  const FeatureMap& features = half ? widened : map;
  const std::size_t pixels = features.pixels();
  if (labels.size() != pixels)
    throw Error(fmt::format("{}: {} labels for a {} x {} feature map", where, labels.size(), features.width(),
                            features.height()));
  if (features.dim() != classifier.dim())
    throw Error(fmt::format("{}: {}-d features but {}-d queries", where, features.dim(), classifier.dim()));
  std::vector<int> truth(pixels);
  PixelCounts counts;
  for (std::size_t i = 0; i < pixels; ++i) {
    truth[i] = ground_truth(labels[i]);
    if (truth[i] == LabelMapping::kUnknown)
      throw Error(fmt::format("{}: label id {} at pixel ({}, {}) of the feature-size label image is not in the "
                              "ontology",
                              where, labels[i], i % features.width(), i / features.width()));
    if (truth[i] == LabelMapping::kIgnore) ++counts.unlabelled;
    else ++counts.pixels;
  }
  score_embeddings(features.values().data(), pixels, truth, classifier, query_to_class, matrix);
  return counts;
}

}  // namespace slamvdb
