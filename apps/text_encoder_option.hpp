#pragma once
// The text encoder of the commands that ask a map with text (`query --text`, `serve`): a TorchScript
// CLIP text encoder from --text-model, or else the SIMULATED one in the map's dimension (said so).
// One function, so that `serve` embeds a text exactly as `query` does.
#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/inference/torch_backend.hpp"

namespace slamvdb::cli {

inline std::unique_ptr<TextEncoder> open_text_encoder(const std::string& text_model, int dim, uint64_t sim_seed,
                                                      float sim_text_gap) {
  if (!text_model.empty()) return open_torch_text_encoder(text_model);
  SimulatedEncoderConfig sim;
  sim.dim = dim;
  sim.seed = sim_seed;
  sim.text_gap = sim_text_gap;
  auto encoder = std::make_unique<SimulatedTextEncoder>(sim);
  spdlog::warn("text is embedded by the SIMULATED text encoder {} (use --text-model for CLIP)", encoder->model_id());
  return encoder;
}

}  // namespace slamvdb::cli
