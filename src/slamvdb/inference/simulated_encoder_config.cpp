// The SIMULATED encoder's settings: their checks, the presets (clean, realistic), the description
// recorded in maps, and the look-alike table its errors draw from.
#include "slamvdb/inference/simulated_encoders.hpp"

#include <fmt/format.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

void validate(const SimulatedEncoderConfig& c) {
  const auto fail = [](const std::string& what) { throw Error("simulated encoder config: " + what); };
  if (c.dim < 1) fail(fmt::format("dim must be >= 1, got {}", c.dim));
  if (c.height < 1 || c.width < 1) fail(fmt::format("feature size must be >= 1 x 1, got {} x {}", c.height, c.width));
  if (!(c.related_cosine >= 0.f && c.related_cosine < 1.f))
    fail(fmt::format("related_cosine must be in [0, 1), got {}", c.related_cosine));
  if (!(c.confusion_rate >= 0.f && c.confusion_rate <= 1.f))
    fail(fmt::format("confusion_rate must be in [0, 1], got {}", c.confusion_rate));
  if (c.confusion_cell < 1) fail(fmt::format("confusion_cell must be >= 1, got {}", c.confusion_cell));
  if (!(c.related_confusion >= 0.f && c.related_confusion <= 1.f))
    fail(fmt::format("related_confusion must be in [0, 1], got {}", c.related_confusion));
  if (!(c.noise_sigma >= 0.f) || !std::isfinite(c.noise_sigma))
    fail(fmt::format("noise_sigma must be >= 0, got {}", c.noise_sigma));
  if (!(c.blur >= 0.f) || !std::isfinite(c.blur)) fail(fmt::format("blur must be >= 0, got {}", c.blur));
  if (!(c.text_gap >= 0.f) || !std::isfinite(c.text_gap))
    fail(fmt::format("text_gap must be >= 0, got {}", c.text_gap));
  if (c.coarse_factor < 1 || c.coarse_factor > 64)
    fail(fmt::format("coarse_factor must be in [1, 64], got {}", c.coarse_factor));
  const std::pair<const char*, float> probabilities[] = {
      {"base_error", c.base_error},         {"range_error", c.range_error},       {"grazing_error", c.grazing_error},
      {"border_error", c.border_error},     {"exposure_error", c.exposure_error}, {"exposure_area", c.exposure_area},
      {"persistence", c.persistence},       {"lookalike_share", c.lookalike_share}};
  for (const auto& [name, v] : probabilities)
    if (!(v >= 0.f && v <= 1.f)) fail(fmt::format("{} must be in [0, 1], got {}", name, v));
  if (!(c.range_near_m >= 0.f && c.range_far_m >= c.range_near_m && std::isfinite(c.range_far_m)))
    fail(fmt::format("range_near_m {} and range_far_m {} must satisfy 0 <= near <= far", c.range_near_m,
                     c.range_far_m));
  if (c.border_px < 0 || c.border_px > 4096) fail(fmt::format("border_px must be in [0, 4096], got {}", c.border_px));
  if (!(c.error_cell_px >= 1.f && c.error_cell_px <= 4096.f))
    fail(fmt::format("error_cell_px must be in [1, 4096], got {}", c.error_cell_px));
  if (!(c.persistence_period_s > 0.f) || !std::isfinite(c.persistence_period_s))
    fail(fmt::format("persistence_period_s must be > 0, got {}", c.persistence_period_s));
}

SimulatedEncoderConfig SimulatedEncoderConfig::clean() {
  SimulatedEncoderConfig c;
  c.confusion_rate = 0.15f;
  c.blur = 1.5f;
  c.coarse_factor = 1;
  c.base_error = c.range_error = c.grazing_error = c.border_error = c.exposure_error = 0.f;
  c.persistence = 0.f;
  c.lookalike_share = 0.f;
  return c;
}

SimulatedEncoderConfig simulated_encoder_preset(std::string_view name, const SimulatedEncoderConfig& base) {
  SimulatedEncoderConfig preset;
  if (name == "clean") preset = SimulatedEncoderConfig::clean();
  else if (name != "realistic")
    throw Error(fmt::format("unknown simulated encoder '{}' (expected clean or realistic)", name));
  preset.dim = base.dim, preset.height = base.height, preset.width = base.width, preset.seed = base.seed;
  preset.related_cosine = base.related_cosine, preset.text_gap = base.text_gap;
  preset.output_precision = base.output_precision;
  return preset;
}

std::string SimulatedEncoderConfig::describe() const {
  const SimulatedEncoderConfig clean_config = simulated_encoder_preset("clean", *this);
  const SimulatedEncoderConfig realistic_config = simulated_encoder_preset("realistic", *this);
  const char* name = *this == clean_config ? "clean" : *this == realistic_config ? "realistic" : "custom";
  return fmt::format(
      "{} (SIMULATED): low resolution x{}; errors base {:.2f}, range {:.2f} ({:g}..{:g} m), grazing {:.2f}, border "
      "{:.2f} ({} px), exposure {:.2f} ({:.0f}% of a view); persistence {:.2f}; look-alikes {:.2f}; per-view blob "
      "swaps {:.2f}; noise {:.2f}; blur {:.2f} px",
      name, coarse_factor, base_error, range_error, range_near_m, range_far_m, grazing_error, border_error, border_px,
      exposure_error, 100 * exposure_area, persistence, lookalike_share, confusion_rate, noise_sigma, blur);
}

const std::vector<uint16_t>& simulated_lookalikes(uint16_t id) {
  // Each class's look-alikes in OTHER coarse classes, from what dense vision-language features
  // confuse on off-road images: terrain of one texture family (dirt, mud, rubble, concrete,
  // asphalt), vegetation (grass, bush, tree), thin structures against trees, people and vehicles
  // against clutter. The paper's own maps show mud ("bumpy") "classified as a mix of smooth and
  // rough terrain" (section 6.3.2), which is the entry for mud.
  static const std::vector<std::pair<uint16_t, std::vector<uint16_t>>> table = {
      {1, {33, 23, 19}},   // dirt -> mud, concrete, bush
      {3, {19, 33}},       // grass -> bush, mud
      {4, {3, 1}},         // tree -> grass, dirt (trunks, crowns against the ground)
      {5, {1, 23}},        // pole -> dirt, concrete
      {6, {31, 33, 10}},   // water -> puddle, mud, asphalt
      {8, {12, 19}},       // vehicle -> building, bush
      {9, {1, 17}},        // object -> dirt, person
      {10, {1, 33}},       // asphalt -> dirt, mud
      {12, {23, 8}},       // building -> concrete, vehicle
      {15, {1, 33}},       // log -> dirt, mud
      {17, {19, 4}},       // person -> bush, tree
      {18, {3, 1}},        // fence -> grass, dirt
      {19, {3, 1}},        // bush -> grass, dirt
      {23, {1, 34}},       // concrete -> dirt, rubble
      {27, {23, 8}},       // barrier -> concrete, vehicle
      {31, {10, 1}},       // puddle -> asphalt, dirt
      {33, {1, 23, 3}},    // mud -> dirt, concrete, grass
      {34, {1, 23}},       // rubble -> dirt, concrete
  };
  static const std::vector<uint16_t> none;
  for (const auto& [fine, alikes] : table)
    if (fine == id) return alikes;
  return none;
}

}  // namespace slamvdb
