#pragma once
// The one interface behind which every vision-language model sits: a real TorchScript network,
// or the simulated encoders used for synthetic data. The map never sees which one it is.
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/feature_map.hpp"

namespace slamvdb {

// One camera image as the encoders see it. A network reads `rgb`; the simulated encoder reads
// the 2D ground-truth `labels` (CV_8UC1 class ids). Either may be empty when not available.
struct ImageFrame {
  double stamp = 0.0;
  cv::Mat rgb;     // CV_8UC3, RGB order
  cv::Mat labels;  // CV_8UC1
  std::string source;  // file name, for messages
  // CV_16UC3: a SIMULATED sequence's per-pixel view geometry (core/simulated_view.hpp: range,
  // incidence, world appearance), read by the simulated encoder only; empty for real data.
  cv::Mat view{};
};

class DenseImageEncoder {
 public:
  virtual ~DenseImageEncoder() = default;
  virtual FeatureMap encode(const ImageFrame& frame) = 0;
  // The same into `out`, whose buffer an encoder may reuse: a 512 x 192 x 128 map is 50 MB, and
  // allocating it afresh for every frame faults in (and zeroes) every page of it.
  virtual void encode_into(const ImageFrame& frame, FeatureMap& out) { out = encode(frame); }
  virtual int dim() const = 0;
  virtual std::string model_id() const = 0;
  // What a map records about the features beyond the model id (a simulation's settings).
  virtual std::string description() const { return model_id(); }
};

class ImageEncoder {
 public:
  virtual ~ImageEncoder() = default;
  virtual std::vector<float> encode(const ImageFrame& frame) = 0;
  virtual int dim() const = 0;
  virtual std::string model_id() const = 0;
};

class TextEncoder {
 public:
  virtual ~TextEncoder() = default;
  virtual std::vector<float> encode(std::string_view text) = 0;
  virtual int dim() const = 0;
  virtual std::string model_id() const = 0;
};

}  // namespace slamvdb
