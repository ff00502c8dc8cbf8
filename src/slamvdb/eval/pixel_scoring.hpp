#pragma once
// Scoring classified embeddings (pixels of a feature map, or sampled pixels) against ground-truth
// labels with the map's classification rule, into a ConfusionMatrix over the ontology's classes.
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "slamvdb/core/feature_map.hpp"
#include "slamvdb/eval/confusion_matrix.hpp"
#include "slamvdb/ontology/ontology.hpp"
#include "slamvdb/query/query_classifier.hpp"

namespace slamvdb {

// A ConfusionMatrix over the ontology's classes with its void classes ignored (paper Table 6.1).
ConfusionMatrix ontology_confusion_matrix(const Ontology& ontology);

// Classifies `rows` embeddings (row-major, classifier.dim() each) and adds (truth[i], prediction)
// for every row whose truth is a class index; rows with a negative truth (LabelMapping::kIgnore)
// are skipped. `query_to_class` maps query indices to the matrix's classes (ontology_classes_of);
// an embedding without a class (zero / non-finite) counts as no prediction.
void score_embeddings(const float* embeddings, std::size_t rows, std::span<const int> truth,
                      const QueryClassifier& classifier, std::span<const int> query_to_class,
                      ConfusionMatrix& matrix);

struct PixelCounts {
  uint64_t pixels = 0;      // labelled pixels scored or ignored by the matrix
  uint64_t unlabelled = 0;  // pixels with an unlabelled id (never scored)
};

// Every pixel of one feature map against its labels at the feature resolution (height x width
// ids). Throws Error naming `where` on a size mismatch or an id the ontology does not know.
PixelCounts score_feature_map(const FeatureMap& features, std::span<const uint16_t> labels,
                              const LabelMapping& ground_truth, const QueryClassifier& classifier,
                              std::span<const int> query_to_class, ConfusionMatrix& matrix, std::string_view where);

}  // namespace slamvdb
