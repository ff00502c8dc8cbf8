#pragma once
// Where an image's feature map comes from: an encoder run on the image (a network, or the
// simulated encoder on the label image), or a precomputed .npy file beside the dataset.
#include <memory>
#include <string>

#include "slamvdb/inference/encoders.hpp"
#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

class FeatureSource {
 public:
  virtual ~FeatureSource() = default;
  virtual FeatureMap features_for(const ImageRecord& record) = 0;  // throws Error
  // The same into `out`, reusing its buffer where the source can (DenseImageEncoder::encode_into).
  virtual void features_into(const ImageRecord& record, FeatureMap& out) { out = features_for(record); }
  virtual std::string model_id() const = 0;
  virtual std::string description() const { return model_id(); }  // recorded in maps (MapInfo::features)
};

// Loads the image parts the encoder reads (rgb for a network, labels for the simulation).
class EncoderFeatureSource : public FeatureSource {
 public:
  enum class Input { kRgb, kLabels };
  EncoderFeatureSource(std::unique_ptr<DenseImageEncoder> encoder, Input input)
      : encoder_(std::move(encoder)), input_(input) {}
  FeatureMap features_for(const ImageRecord& record) override;
  void features_into(const ImageRecord& record, FeatureMap& out) override;
  std::string model_id() const override { return encoder_->model_id(); }
  std::string description() const override { return encoder_->description(); }

 private:
  std::unique_ptr<DenseImageEncoder> encoder_;
  Input input_;
};

// One C x H x W .npy per image (ImageRecord::features), for users who run a network offline.
class NpyFeatureSource : public FeatureSource {
 public:
  explicit NpyFeatureSource(std::string model_id) : model_id_(std::move(model_id)) {}
  FeatureMap features_for(const ImageRecord& record) override;
  void features_into(const ImageRecord& record, FeatureMap& out) override;  // fp16 files stay fp16
  std::string model_id() const override { return model_id_; }

 private:
  std::string model_id_;
};

}  // namespace slamvdb
