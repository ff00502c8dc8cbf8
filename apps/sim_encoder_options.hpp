#pragma once
// The SIMULATED encoder's options, shared by every command that runs it (map, demo, eval,
// eval-images, train-queries): a preset (`--sim-encoder realistic|clean`) and one option per failure
// mode to switch it off or change it (ablation). A failure-mode option given on the command line or
// in --config overrides the preset; options not given take the preset's value and are not written
// into a map's recorded configuration, so that a recorded `sim-encoder: clean` re-runs clean.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "option_checks.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"

namespace slamvdb::cli {

class SimEncoderOptions {
 public:
  std::string preset = "realistic";

  void add_to(CLI::App* cmd) {
    cmd->add_option("--sim-encoder", preset,
                    "SIMULATED encoder: 'realistic' fails as dense vision-language networks do on off-road images "
                    "(low resolution, view-dependent, persistent and look-alike errors; about 78% pixel accuracy per "
                    "image on the default drive), 'clean' is the earlier near-perfect one (96%). The --sim-* options "
                    "below override single failure modes of the preset (0 switches one off)")
        ->capture_default_str()
        ->check(CLI::IsMember({"realistic", "clean"}));
    const auto probability = [&](const char* name, float SimulatedEncoderConfig::*field, const char* what) {
      auto value = std::make_shared<float>(0.f);
      CLI::Option* o = cmd->add_option(name, *value, what)->check(finite_range(0, 1));
      overrides_.push_back({o, [value, field](SimulatedEncoderConfig& c) { c.*field = *value; }});
    };
    auto coarse = std::make_shared<int>(1);
    overrides_.push_back(
        {cmd->add_option("--sim-coarse-factor", *coarse,
                         "SIMULATED low resolution: class evidence averaged over N x N feature pixels and upsampled "
                         "(realistic: 2; 1 = off)")
             ->check(integer_range(1, 64)),
         [coarse](SimulatedEncoderConfig& c) { c.coarse_factor = *coarse; }});
    probability("--sim-base-error", &SimulatedEncoderConfig::base_error,
                "SIMULATED error probability of every pixel (realistic: 0.18)");
    probability("--sim-range-error", &SimulatedEncoderConfig::range_error,
                "SIMULATED extra error probability of far surfaces (ramps from 5 m to 40 m; realistic: 0.30)");
    probability("--sim-grazing-error", &SimulatedEncoderConfig::grazing_error,
                "SIMULATED extra error probability at grazing incidence (realistic: 0.15)");
    probability("--sim-border-error", &SimulatedEncoderConfig::border_error,
                "SIMULATED extra error probability at the image border (realistic: 0.25)");
    probability("--sim-exposure-error", &SimulatedEncoderConfig::exposure_error,
                "SIMULATED extra error probability in over- or under-exposed regions (realistic: 0.45)");
    probability("--sim-persistence", &SimulatedEncoderConfig::persistence,
                "SIMULATED share of the error field fixed to the world, so that a place errs alike in every view "
                "(realistic: 0.35; 0: views err independently)");
    probability("--sim-lookalike", &SimulatedEncoderConfig::lookalike_share,
                "SIMULATED share of errors that show a look-alike class of another coarse class (realistic: 0.7)");
    probability("--sim-confusion", &SimulatedEncoderConfig::confusion_rate,
                "SIMULATED per-view blob swaps: share of 16-pixel cells relabelled in each view (clean: 0.15, "
                "realistic: 0)");
    probability("--sim-related-confusion", &SimulatedEncoderConfig::related_confusion,
                "SIMULATED share of errors that pick a class of the same coarse class (0.75)");
  }

  // The preset with the given overrides; dim, size, seed, text gap and precision come from `base`.
  SimulatedEncoderConfig config(const SimulatedEncoderConfig& base) const {
    SimulatedEncoderConfig c = simulated_encoder_preset(preset, base);
    for (const auto& [option, apply] : overrides_)
      if (option->count() > 0) apply(c);
    return c;
  }

 private:
  std::vector<std::pair<CLI::Option*, std::function<void(SimulatedEncoderConfig&)>>> overrides_;
};

}  // namespace slamvdb::cli
