#include "slamvdb/eval/image_baseline.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/eval/label_images.hpp"
#include "slamvdb/eval/pixel_scoring.hpp"

namespace slamvdb {

ImageBaselineResult evaluate_image_baseline(std::span<const ImageRecord> images, FeatureSource& features,
                                            const QuerySet& queries, const Ontology& ontology,
                                            const ImageBaselineOptions& options, const ImageProgress& progress) {
  check_compatible(queries, queries.dim(), features.model_id(), options.model_check);  // model id first
  const std::vector<int> query_to_class = ontology_classes_of(queries, ontology);
  const QueryClassifier classifier(queries, options.classify);
  const LabelMapping truth = ontology.ground_truth();
  ImageBaselineResult result{ontology_confusion_matrix(ontology)};
  for (std::size_t i = 0; i < images.size(); ++i) {
    const ImageRecord& image = images[i];
    if (image.labels.empty()) {
      ++result.without_labels;
    } else {
      const FeatureMap map = features.features_for(image);
      const std::string where = image.labels.filename().string();
      check_compatible(queries, map.dim(), features.model_id(), ModelIdCheck::kIgnore);  // the dimension
      const std::vector<uint16_t> labels = read_labels_at(image.labels, map.width(), map.height());
      const PixelCounts counts = score_feature_map(map, labels, truth, classifier, query_to_class, result.matrix, where);
      result.pixels += counts.pixels;
      result.unlabelled_pixels += counts.unlabelled;
      ++result.images;
    }
    if (progress) progress(i + 1, images.size());
  }
  return result;
}

}  // namespace slamvdb
