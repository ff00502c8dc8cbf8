#pragma once
// SIMULATED vision-language encoders for synthetic data and tests: no network, no image content.
// The dense encoder turns a frame's 2D ground-truth label image into LSeg-like per-pixel features
// with the defects of a real one (coarse, wrong in blobs that depend on the view and persist across
// views, noisy, blurred at class boundaries: SimulatedEncoderConfig); the text
// encoder maps RELLIS-3D class names into the same space. One prototype unit vector per fine
// class, fixed by the seed; classes in the same coarse class (core/ontology.hpp) are correlated.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/inference/encoders.hpp"

namespace slamvdb {

// The SIMULATED encoder's settings. The defaults are the REALISTIC encoder: it fails the way dense
// vision-language networks fail on off-road images (README, "The simulated encoder"), calibrated so
// that classifying each image on its own scores 75-85 % pixel accuracy on the default SIMULATED drive.
// clean() is the encoder this project had before: per-view blob swaps, noise and blur only, 96 %
// per image. Every failure mode is switched off by setting its parameter to 0 (coarse_factor 1).
struct SimulatedEncoderConfig {
  int dim = 512;
  int height = 128, width = 192;  // feature map size (LSeg at the paper's 128 x 192); labels are resampled to it
  uint64_t seed = 1;
  float related_cosine = 0.5f;     // cosine between prototypes of two classes of one coarse class

  // Per-view blob swaps (the clean encoder's errors): cells of confusion_cell feature pixels, on a
  // grid offset per view, relabelled with probability confusion_rate, a class of the same coarse
  // class preferred (related_confusion). Independent between views: fusion averages them away.
  float confusion_rate = 0.0f;
  int confusion_cell = 16;
  float related_confusion = 0.75f;
  float noise_sigma = 0.8f;        // norm of the per-pixel noise relative to the unit prototype
  float blur = 1.0f;               // Gaussian sigma in feature pixels mixing classes at boundaries

  // ---- failure modes of real networks (each 0 = off) ----
  // Low resolution: class evidence is averaged over cells of coarse_factor x coarse_factor feature
  // pixels and upsampled bilinearly, so boundaries blur and thin objects (poles, trunks, fences)
  // smear into their background. LSeg's decoder outputs 1/2 of its input, but its ViT-L/16 sees
  // 16-pixel patches; 2 (a 64 x 96 grid at 128 x 192) is the decoder's own output grid.
  int coarse_factor = 2;
  // Where the network errs, pixel by pixel: the probability that a pixel shows a wrong class is
  //   base_error + range_error * ramp(range; range_near_m..range_far_m)
  //   + grazing_error * ramp(1 - cos incidence; 0.5..1) + border_error * ramp(border distance; border_px..0)
  //   + exposure_error in badly exposed regions (about exposure_area of each view),
  // capped at 0.9. Range and incidence come from the SIMULATED view geometry a synthetic sequence
  // carries (synth/camera_sim.hpp); without it (real data) those two terms are 0.
  float base_error = 0.18f;
  float range_error = 0.30f;
  float range_near_m = 5.0f, range_far_m = 40.0f;
  float grazing_error = 0.15f;
  float border_error = 0.25f;
  int border_px = 10;
  float exposure_error = 0.45f;
  float exposure_area = 0.08f;
  // Which pixels err: those where a smooth random field (blobs of about error_cell_px) falls below
  // the quantile of their error probability. The field is sqrt(persistence) x a world-fixed field
  // (the same place looks alike in every view: the view geometry's appearance channel; without it
  // an image-space field that changes slowly, over persistence_period_s) plus sqrt(1 - persistence)
  // x a field drawn anew for each view. 0: every view errs independently (fusion averages errors
  // away); 1: a place is confused in every view alike.
  float persistence = 0.35f;
  float error_cell_px = 10.0f;
  float persistence_period_s = 2.0f;
  // The class an erring pixel shows: with probability lookalike_share a look-alike of its true
  // class that belongs to another coarse class (mud -> dirt or concrete, grass -> bush, pole ->
  // tree, person -> bush, ...: simulated_lookalikes()), else a class of the same coarse class
  // (related_confusion) or any other. The choice is keyed to the world field too, so a persistent
  // error persists with the same wrong class.
  float lookalike_share = 0.7f;

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

  // The encoder this project had before the realistic one (96 % pixel accuracy per image on the
  // default drive): per-view blob swaps, noise and blur, no other failure mode.
  static SimulatedEncoderConfig clean();
  // The failure modes as one line ("realistic: low resolution x4, ..."), for logs and map files.
  std::string describe() const;
  bool operator==(const SimulatedEncoderConfig&) const = default;
};

// "clean" or "realistic" (the defaults); throws Error naming the choices otherwise. Only the
// failure modes differ: dim, size, seed, text gap and precision are kept from `base`.
SimulatedEncoderConfig simulated_encoder_preset(std::string_view name, const SimulatedEncoderConfig& base = {});

// RELLIS-3D look-alikes across coarse classes (by fine class id): what a real network confuses a
// class with when it errs. Empty for classes without one.
const std::vector<uint16_t>& simulated_lookalikes(uint16_t fine_id);

// Throws Error naming the first parameter out of range.
void validate(const SimulatedEncoderConfig& config);

// Row i is the prototype of rellis_classes()[i]: normalize(a * coarse vector + b * class vector)
// with a^2 = related_cosine, a^2 + b^2 = 1, the vectors Gaussian from the seed.
using PrototypeMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
PrototypeMatrix simulated_class_prototypes(const SimulatedEncoderConfig& config);

// The embedding space the three encoders share: "simulated-lseg-v1(seed=..,dim=..,related=..)".
std::string simulated_model_id(const SimulatedEncoderConfig& config);

// Per view (randomness from seed and frame stamp, so deterministic): labels resampled to
// height x width (nearest); pixels relabelled where the failure modes above make them err (and
// whole cells with probability confusion_rate); each class's evidence averaged over the coarse
// grid, upsampled and blurred across class boundaries; noise added per pixel; L2-normalised. Reads
// the frame's view geometry when it has one (CV_16UC3, any size: resampled like the labels).
// Throws Error if the frame has no CV_8UC1 label image or holds an id that is no RELLIS-3D class.
class SimulatedDenseEncoder : public DenseImageEncoder {
 public:
  explicit SimulatedDenseEncoder(SimulatedEncoderConfig config = {});
  FeatureMap encode(const ImageFrame& frame) override;
  void encode_into(const ImageFrame& frame, FeatureMap& out) override;
  int dim() const override { return config_.dim; }
  std::string model_id() const override { return simulated_model_id(config_); }
  std::string description() const override { return "simulated encoder " + config_.describe(); }
  const SimulatedEncoderConfig& config() const { return config_; }

 private:
  static constexpr int kNoiseBankSize = 1024;  // 2 MB at dim 512: stays in cache
  // The wrong class an erring pixel of class row k shows, chosen by `key`.
  int wrong_class(int k, uint64_t key) const;
  SimulatedEncoderConfig config_;
  PrototypeMatrix prototypes_;
  std::vector<std::vector<int>> related_, lookalike_;  // per class row: rows of the same coarse class; look-alikes
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
