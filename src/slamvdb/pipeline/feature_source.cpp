#include "slamvdb/pipeline/feature_source.hpp"

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/io/npy.hpp"

namespace slamvdb {

FeatureMap EncoderFeatureSource::features_for(const ImageRecord& record) {
  FeatureMap out;
  features_into(record, out);
  return out;
}

void EncoderFeatureSource::features_into(const ImageRecord& record, FeatureMap& out) {
  const bool rgb = input_ == Input::kRgb;
  if (!(rgb ? record.has_rgb() : record.has_labels()))
    throw Error("image at stamp " + std::to_string(record.stamp) + " has no " + (rgb ? "RGB file" : "label image"));
  encoder_->encode_into(load_image_frame(record, rgb, !rgb), out);
}

FeatureMap NpyFeatureSource::features_for(const ImageRecord& record) {
  FeatureMap out;
  features_into(record, out);
  return out;
}

void NpyFeatureSource::features_into(const ImageRecord& record, FeatureMap& out) {
  if (record.features.empty())
    throw Error("image " + record.rgb.filename().string() + " has no precomputed feature file");
  read_feature_npy(record.features, out);
}

}  // namespace slamvdb
