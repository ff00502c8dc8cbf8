#pragma once
// The SIMULATED encoder's options, shared by every command that runs it (map, demo, eval,
// eval-images, train-queries): a preset (`--sim-encoder realistic|clean`) and one option per failure
// mode to switch it off or change it (ablation). A failure-mode option given on the command line or
// in --config overrides the preset; options not given take the preset's value and are not written
// into a map's recorded configuration, so that a recorded `sim-encoder: clean` re-runs clean.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "option_checks.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/dataset.hpp"
#include "slamvdb/io/rellis_reader.hpp"

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

// The SIMULATED encoder reads range, incidence and a world-fixed appearance per pixel from the view
// geometry images synth writes beside the camera images. Without them (a sequence written before
// synth wrote them, or real data) its range and grazing errors are off and its persistent errors
// follow the image instead of the world: the same settings give other figures. Said once per run.
inline void warn_missing_view_geometry(const Sequence& seq, const SimulatedEncoderConfig& sim) {
  if (sim.range_error == 0.f && sim.grazing_error == 0.f && sim.persistence == 0.f) return;
  std::size_t labelled = 0, without = 0;
  for (const ImageRecord& img : seq.images)
    if (!img.labels.empty()) ++labelled, without += img.view.empty();
  if (without > 0)
    spdlog::warn("{} of {} labelled images have no SIMULATED view geometry ({}/): the SIMULATED encoder's range and "
                 "grazing errors are off for them and its persistent errors follow the image, not the world (run "
                 "`slamvdb synth` again to get it)",
                 without, labelled, kRellisSimViewDir);
}

}  // namespace slamvdb::cli
