#pragma once
// The failure modes of the SIMULATED dense encoder (simulated_encoders.hpp): which pixels of a view
// show a wrong class, and which wrong class. Internal to the inference part.
#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

#include "slamvdb/inference/simulated_encoders.hpp"

namespace slamvdb::sim_failures {

// A smooth field of H x W values, standard normal at every pixel (bilinear interpolation of iid
// Gaussian lattice values `cell` pixels apart, renormalised by the interpolation weights), keyed by
// `key`: the same key gives the same field.
void smooth_field(uint64_t key, int height, int width, float cell, float* out);

// Per pixel of a height x width view: whether it errs, and the value of the field it errs by (the
// world-fixed part when there is one), which keys the wrong class so that a persistent error keeps
// its class.
struct PixelErrors {
  std::vector<uint8_t> wrong;    // 1: the pixel shows a wrong class
  std::vector<float> choice;     // keys the wrong class (world-fixed where the view geometry has it)
  std::size_t count = 0;         // wrong pixels
};

// `labels`: height x width class rows (index into rellis_classes(), -1 for void classes, which never
// err); `view`: the view geometry resampled to height x width (CV_16UC3) or empty. Deterministic in
// (config.seed, stamp).
PixelErrors pixel_errors(const SimulatedEncoderConfig& config, const std::vector<int>& labels, const cv::Mat& view,
                         double stamp, uint64_t view_key);

// The probability that a pixel errs, without the exposure term (for tests and the README's figures).
float error_probability(const SimulatedEncoderConfig& config, double range_m, double incidence_cos, int border_px);

}  // namespace slamvdb::sim_failures
