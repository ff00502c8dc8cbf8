#pragma once
// The image encoder of the commands that ask a map with an image (`query --image`, `serve`'s
// POST /api/query "image"): a TorchScript CLIP image encoder from --image-model (reads RGB), or else
// the SIMULATED one in the map's dimension, which reads a 2D label image (said so). One function,
// so that `serve` embeds an image exactly as `query` does (io/query_image.hpp embeds it).
#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/query_image.hpp"
#include "slamvdb/inference/torch_backend.hpp"

namespace slamvdb::cli {

inline std::unique_ptr<QueryImageEncoder> open_image_encoder(const std::string& image_model, int dim, uint64_t sim_seed) {
  if (!image_model.empty()) return std::make_unique<QueryImageEncoder>(open_torch_image_encoder(image_model), false);
  SimulatedEncoderConfig sim;
  sim.dim = dim;
  sim.seed = sim_seed;
  spdlog::warn("images are embedded by the SIMULATED image encoder from their 2D label image (use --image-model "
               "for a network on RGB)");
  return std::make_unique<QueryImageEncoder>(std::make_unique<SimulatedImageEncoder>(sim), true);
}

}  // namespace slamvdb::cli
