#pragma once
// The per-image baseline: every pixel of every labelled image classified directly with the query
// vectors (the same rule as the map, void -> second best included) and scored against the image's
// 2D labels at the feature resolution (void ignored), so that what fusing views into voxels gains
// is measured, not assumed.
#include <cstddef>
#include <functional>
#include <span>

#include "slamvdb/eval/confusion_matrix.hpp"
#include "slamvdb/io/dataset.hpp"
#include "slamvdb/ontology/ontology.hpp"
#include "slamvdb/pipeline/feature_source.hpp"
#include "slamvdb/query/query_classifier.hpp"

namespace slamvdb {

struct ImageBaselineOptions {
  ClassifyOptions classify;  // void -> second best on by default, as on the map
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;
};

struct ImageBaselineResult {
  ConfusionMatrix matrix;           // over the ontology's classes, void ignored
  std::size_t images = 0;           // images scored
  std::size_t without_labels = 0;   // images skipped because they have no label image
  uint64_t pixels = 0;              // labelled pixels (scored + void)
  uint64_t unlabelled_pixels = 0;   // pixels with an unlabelled id
};

using ImageProgress = std::function<void(std::size_t done, std::size_t total)>;

// Throws Error (naming the image) on queries from another embedding space (check_compatible),
// query names that are no ontology class, unreadable images or unknown label ids.
ImageBaselineResult evaluate_image_baseline(std::span<const ImageRecord> images, FeatureSource& features,
                                            const QuerySet& queries, const Ontology& ontology,
                                            const ImageBaselineOptions& options = {},
                                            const ImageProgress& progress = {});

}  // namespace slamvdb
