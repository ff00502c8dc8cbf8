#pragma once
// Options shared by the commands that read image features and labelled images (train-queries,
// eval-images): where features come from, the simulated encoder's settings (the same flags and
// defaults as `map`, so the model ids match), text encoders, and which images to use.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <charconv>
#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <vector>

#include "option_checks.hpp"
#include "io_options.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/dataset.hpp"
#include "slamvdb/pipeline/feature_source.hpp"
#include "sim_encoder_options.hpp"
#include "slamvdb/inference/torch_backend.hpp"

namespace slamvdb::cli {

// Readable range checks (CLI11's PositiveNumber prints the largest double as the bound).
inline CLI::Validator at_least(double low, bool inclusive) {
  return CLI::Validator(
      [low, inclusive](std::string& text) -> std::string {
        double v = 0;
        const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
        if (ec != std::errc() || end != text.data() + text.size()) return "'" + text + "' is not a number";
        if (!(inclusive ? v >= low : v > low)) return fmt::format("must be {} {}, got {}", inclusive ? ">=" : ">", low, text);
        return {};
      },
      inclusive ? fmt::format(">= {}", low) : fmt::format("> {}", low));
}
inline const CLI::Validator kPositive = at_least(0, false);
inline const CLI::Validator kNonNegative = at_least(0, true);

struct FeatureOptions {
  std::string features = "simulated";
  std::string model, text_model, precomputed_model_id;
  int threads = -1;
  int dim = 512;
  std::string feature_size = "192x128";
  uint64_t sim_seed = 1;
  float sim_text_gap = 0.f;
  SimEncoderOptions sim_encoder;
  std::string images;       // FIRST:LAST (0-based, inclusive) among the labelled images
  std::size_t max_images = 0;
};

// with_image_selection: --images / --max-images (commands that go through select_labelled_images).
// with_none: mapping commands also take 'none' (geometry only).
inline void add_feature_options(CLI::App* cmd, FeatureOptions& o, bool with_text_model, bool with_image_selection = true,
                                bool with_none = false) {
  std::vector<std::string> choices{"simulated", "model", "precomputed"};
  if (with_none) choices.push_back("none");
  cmd->add_option("--features", o.features,
                  std::string("Where image features come from: 'simulated' (SIMULATED from the 2D label images, no "
                              "network), 'model' (a TorchScript dense encoder, --model), 'precomputed' "
                              "(features/<image>.npy)") +
                      (with_none ? ", 'none' (geometry only)" : ""))
      ->capture_default_str()
      ->check(CLI::IsMember(choices));
  cmd->add_option("--model", o.model, "TorchScript dense image encoder (MODEL.pt with MODEL.json beside it)")
      ->check(CLI::ExistingFile);
  if (with_text_model)
    cmd->add_option("--text-model", o.text_model,
                    "TorchScript text encoder (CLIP) for the initial queries; SIMULATED features use the simulated "
                    "text encoder")
        ->check(CLI::ExistingFile);
  cmd->add_option("--features-model-id", o.precomputed_model_id,
                  "With --features precomputed: the model id of the network that wrote the .npy files, so that "
                  "queries and maps from different sequences share it (default: precomputed:<dataset>)");
  cmd->add_option("--threads", o.threads, "Network threads (-1: the manifest's setting)")
      ->capture_default_str()
      ->check(integer_range(-1, bounds::kMaxThreads));
  cmd->add_option("--dim", o.dim, "Simulated embedding dimension")
      ->capture_default_str()
      ->check(integer_range(1, bounds::kMaxDim));
  cmd->add_option("--feature-size", o.feature_size, "Simulated feature map size WIDTHxHEIGHT")->capture_default_str();
  cmd->add_option("--sim-seed", o.sim_seed, "Seed of the simulated encoder")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  o.sim_encoder.add_to(cmd);
  if (with_text_model)
    cmd->add_option("--sim-text-gap", o.sim_text_gap,
                    "SIMULATED text-image gap of the simulated text encoder: 0 = ideal text embeddings; g > 0 mixes "
                    "g x other classes' prototypes into each name's embedding, as CLIP's text embeddings are off "
                    "(paper Figure 6.3)")
        ->capture_default_str()
        ->check(kNonNegative);
  if (!with_image_selection) return;
  auto* images = cmd->add_option("--images", o.images,
                                 "Use the labelled images FIRST:LAST (0-based, inclusive, in time order)");
  cmd->add_option("--max-images", o.max_images, "Use only the first N labelled images (0: all)")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxCount))
      ->excludes(images);
}

// Usage errors found before any work: CLI::ValidationError (exit 2).
inline void check_feature_options(const FeatureOptions& o) {
  if (o.features == "model" && o.model.empty())
    throw CLI::ValidationError("--features model", "needs --model MODEL.pt (a TorchScript dense encoder)");
  if (!o.model.empty() && o.features != "model")
    throw CLI::ValidationError("--model", "is only used with --features model");
  if (!o.precomputed_model_id.empty() && o.features != "precomputed")
    throw CLI::ValidationError("--features-model-id", "is only used with --features precomputed");
  if (o.features == "simulated") check_simulated_feature_size(o.feature_size, o.dim, 4);  // fp32 feature maps
  if (!o.images.empty()) {
    static const std::regex kRange(R"((\d{1,9}):(\d{1,9}))");
    std::smatch m;
    if (!std::regex_match(o.images, m, kRange) || std::stoul(m[1]) > std::stoul(m[2]))
      throw CLI::ValidationError("--images", fmt::format("'{}' is not FIRST:LAST with FIRST <= LAST", o.images));
  }
}

inline SimulatedEncoderConfig simulated_config(const FeatureOptions& o) {
  SimulatedEncoderConfig sim;
  const auto x = o.feature_size.find_first_of("xX");
  sim.width = std::stoi(o.feature_size.substr(0, x));
  sim.height = std::stoi(o.feature_size.substr(x + 1));
  sim.dim = o.dim;
  sim.seed = o.sim_seed;
  sim.text_gap = o.sim_text_gap;
  return o.sim_encoder.config(sim);
}

inline std::unique_ptr<FeatureSource> make_feature_source(const FeatureOptions& o, const Sequence& seq) {
  if (o.features == "model") {
    auto encoder = open_torch_dense_image_encoder(o.model, TorchEncoderOptions{.threads = o.threads});
    spdlog::info("network {}: {}-d features", escape_control(encoder->model_id()), encoder->dim());
    return std::make_unique<EncoderFeatureSource>(std::move(encoder), EncoderFeatureSource::Input::kRgb);
  }
  if (o.features == "precomputed") {
    for (const auto& img : seq.images)
      if (!img.features.empty())
        return std::make_unique<NpyFeatureSource>(
            o.precomputed_model_id.empty() ? "precomputed:" + seq.root.string() : o.precomputed_model_id);
    throw Error(fmt::format("--features precomputed: no features/<image>.npy files in {}", seq.root.string()));
  }
  const SimulatedEncoderConfig sim = simulated_config(o);
  spdlog::warn("features are SIMULATED from the 2D label images (no network): {}; encoder {}", simulated_model_id(sim),
               sim.describe());
  warn_missing_view_geometry(seq, sim);
  return std::make_unique<EncoderFeatureSource>(std::make_unique<SimulatedDenseEncoder>(sim),
                                                EncoderFeatureSource::Input::kLabels);
}

// The text encoder for initial queries: --text-model, else the simulated one for simulated
// features, else none.
inline std::unique_ptr<TextEncoder> make_text_encoder(const FeatureOptions& o) {
  if (!o.text_model.empty()) {
    return open_torch_text_encoder(o.text_model, TorchEncoderOptions{.threads = o.threads});
  }
  if (o.features == "simulated") return std::make_unique<SimulatedTextEncoder>(simulated_config(o));
  return nullptr;
}

// The labelled images selected by --images / --max-images, in time order; reports how many of
// the sequence's images have no label image.
inline std::vector<ImageRecord> select_labelled_images(const Sequence& seq, const FeatureOptions& o) {
  std::vector<ImageRecord> labelled;
  for (const auto& img : seq.images)
    if (!img.labels.empty()) labelled.push_back(img);
  if (labelled.size() < seq.images.size())
    spdlog::info("{} of {} images have no 2D label image and are not used", seq.images.size() - labelled.size(),
                 seq.images.size());
  if (labelled.empty()) throw Error(fmt::format("{}: no image has a 2D label image", seq.root.string()));
  if (!o.images.empty()) {
    const auto colon = o.images.find(':');
    const std::size_t first = std::stoul(o.images.substr(0, colon)), last = std::stoul(o.images.substr(colon + 1));
    if (last >= labelled.size())
      throw Error(fmt::format("--images {}: the sequence has {} labelled images (0:{})", o.images, labelled.size(),
                              labelled.size() - 1));
    return std::vector<ImageRecord>(labelled.begin() + first, labelled.begin() + last + 1);
  }
  if (o.max_images > 0 && o.max_images < labelled.size()) labelled.resize(o.max_images);
  return labelled;
}

// The model files of the feature options, as inputs of the command (io_options.hpp).
inline void add_feature_inputs(IoOptions& io, const FeatureOptions& o) {
  io.input("--model", o.model);
  io.input("--text-model", o.text_model);
}

}  // namespace slamvdb::cli
