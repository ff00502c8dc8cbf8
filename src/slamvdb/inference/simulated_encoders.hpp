#pragma once
// SIMULATED vision-language encoders for synthetic data and tests: no network, no image content.
// The dense encoder turns a frame's 2D ground-truth label image into LSeg-like per-pixel features
// with the defects of a real one (wrong in blobs, noisy, blurred at class boundaries); the text
// encoder maps RELLIS-3D class names into the same space. One prototype unit vector per fine
// class, fixed by the seed; classes in the same coarse class (core/ontology.hpp) are correlated.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "slamvdb/inference/encoders.hpp"

namespace slamvdb {

struct SimulatedEncoderConfig {
  int dim = 512;
  int height = 128, width = 192;  // feature map size; labels are resampled to it
  uint64_t seed = 1;
  float related_cosine = 0.5f;     // cosine between prototypes of two classes of one coarse class
  float confusion_rate = 0.15f;    // fraction of cells per view whose classes are swapped
  int confusion_cell = 16;         // cell side in feature pixels
  float related_confusion = 0.75f; // chance that a swap picks a related class (when there is one)
  float noise_sigma = 0.8f;        // norm of the per-pixel noise relative to the unit prototype
  float blur = 1.5f;               // Gaussian sigma in feature pixels mixing classes at boundaries
  // Text encoder only: SIMULATED text-image gap. 0 (default): a class name's text embedding is
  // its image prototype, an ideal text encoder. g > 0: each name's embedding is its ideal vector
  // plus g times a random mix of OTHER classes' prototypes (weights concentrated on a few), as a
  // CLIP text embedding of one class resembles image features of others, so that some queries
  // "drown out" the rest (paper section 6.2.5, Figure 6.3). Does not change the image space.
  float text_gap = 0.f;
  // Dense encoder only: the precision of the feature maps it hands over. kFloat16 rounds each value
  // of the fp32 features to fp16, as a network run in half precision delivers them (the values are
  // the fp32 ones rounded, nothing else changes: the model id stays the same).
  EmbeddingPrecision output_precision = EmbeddingPrecision::kFloat32;
};

// Throws Error naming the first parameter out of range.
void validate(const SimulatedEncoderConfig& config);

// Row i is the prototype of rellis_classes()[i]: normalize(a * coarse vector + b * class vector)
// with a^2 = related_cosine, a^2 + b^2 = 1, the vectors Gaussian from the seed.
using PrototypeMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
PrototypeMatrix simulated_class_prototypes(const SimulatedEncoderConfig& config);

// The embedding space the three encoders share: "simulated-lseg-v1(seed=..,dim=..,related=..)".
std::string simulated_model_id(const SimulatedEncoderConfig& config);

// Per view (randomness from seed and frame stamp, so deterministic): labels resampled to
// height x width (nearest), whole cells of confusion_cell pixels relabelled with probability
// confusion_rate (on a grid offset per view), prototypes blurred across class boundaries, noise
// added per pixel, L2-normalised. Throws Error if the frame has no CV_8UC1 label image or holds
// an id that is no RELLIS-3D class.
class SimulatedDenseEncoder : public DenseImageEncoder {
 public:
  explicit SimulatedDenseEncoder(SimulatedEncoderConfig config = {});
  FeatureMap encode(const ImageFrame& frame) override;
  void encode_into(const ImageFrame& frame, FeatureMap& out) override;
  int dim() const override { return config_.dim; }
  std::string model_id() const override { return simulated_model_id(config_); }
  const SimulatedEncoderConfig& config() const { return config_; }

 private:
  static constexpr int kNoiseBankSize = 1024;  // 2 MB at dim 512: stays in cache
  SimulatedEncoderConfig config_;
  PrototypeMatrix prototypes_;
  std::vector<float> noise_bank_;      // kNoiseBankSize x dim, unit expected norm per row
  std::array<int, 256> class_row_{};   // RELLIS id -> prototype row, -1 if no class
};

// RELLIS-3D class names ("grass"), coarse class names ("rough": the normalised mean of its fine
// classes; "void" is the fine class), and phrases naming them ("tall grass", "two trees") map to
// the prototypes (moved by config.text_gap when it is > 0); a phrase naming several averages
// them. Anything else is an Error listing the known names.
class SimulatedTextEncoder : public TextEncoder {
 public:
  explicit SimulatedTextEncoder(SimulatedEncoderConfig config = {});
  std::vector<float> encode(std::string_view text) override;
  int dim() const override { return config_.dim; }
  std::string model_id() const override { return simulated_model_id(config_); }

 private:
  SimulatedEncoderConfig config_;
  std::vector<std::pair<std::string, Eigen::VectorXf>> names_;  // fine names first, then coarse
};

// The normalised mean of the simulated dense features of the frame.
class SimulatedImageEncoder : public ImageEncoder {
 public:
  explicit SimulatedImageEncoder(SimulatedEncoderConfig config = {}) : dense_(config) {}
  std::vector<float> encode(const ImageFrame& frame) override;
  int dim() const override { return dense_.dim(); }
  std::string model_id() const override { return dense_.model_id(); }

 private:
  SimulatedDenseEncoder dense_;
};

}  // namespace slamvdb
