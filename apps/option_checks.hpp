#pragma once
// Checks of numeric command-line options, shared by the subcommands: every value is validated
// before any work starts, and a bad one is a usage error (exit code 2) naming the option.
// CLI::Range alone is not enough for floating-point options: NaN compares false with both
// bounds and slips through, so finite_range() refuses NaN and inf explicitly.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <regex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/core/error.hpp"

namespace slamvdb::cli {

// Documented upper bounds (README "CLI option bounds"). They are far above any real use and keep
// a typo (1e9 for 1e2) from running for hours or exhausting memory.
namespace bounds {
inline constexpr double kMaxRange = 1000.0;           // m: --max-range, --max-clearing-range, --max-depth
inline constexpr double kMinVoxelSize = 0.01;         // m
inline constexpr double kMaxVoxelSize = 100.0;        // m
inline constexpr double kMaxRaySteps = 100'000.0;     // voxels traversed per ray: max-clearing-range / voxel-size
inline constexpr int kMaxDim = 4096;                  // embedding dimension (CLIP / LSeg: 512, the largest CLIPs 1280)
inline constexpr int kMaxQueue = 64;                  // inference queue (each entry holds one feature map)
inline constexpr int kMaxThreads = 256;               // network threads (also the manifests' runtime.threads)
inline constexpr double kMaxFeatureMapBytes = 1 << 30;  // dim x width x height x 4 (2 in fp16) of one simulated feature map
inline constexpr int kMaxFeatureSide = 4096;          // simulated feature map side
inline constexpr double kMaxSynthLength = 100'000.0;  // m: synth --length (100 km; about 2 MB per metre at defaults)
inline constexpr double kMaxResolution = 1000.0;      // m per pixel: export --resolution
inline constexpr double kMinResolution = 0.001;       // m per pixel
inline constexpr double kMaxImagePixels = 1e10;       // --max-image-pixels
inline constexpr std::int64_t kMaxSeed = INT64_MAX;   // seeds of the simulations and of training: [0, 2^63 - 1]
inline constexpr std::int64_t kMaxCount = 1'000'000'000;  // counts: scans, images, results, epochs, failures
inline constexpr int kMaxLidarColumns = 8192;         // synth --lidar-columns (an OS1 has at most 2048)
}  // namespace bounds

// A finite number in [min, max] (or (min, max] with min_exclusive). Shown in --help as "in [a, b]".
inline CLI::Validator finite_range(double min, double max, bool min_exclusive = false) {
  const std::string range = fmt::format("{}{}, {}]", min_exclusive ? "(" : "[", min, max);
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(text, v)) return fmt::format("'{}' is not a number", text);
        if (!std::isfinite(v)) return fmt::format("{} is not a finite number (expected a number in {})", text, range);
        if (v < min || v > max || (min_exclusive && v == min))
          return fmt::format("{} is out of range: expected a number in {}", text, range);
        return {};
      },
      "in " + range, "FINITE_RANGE");
}

// An integer in [min, max], written in decimal. CLI11 converts integers with strtoull/strtoll in
// base 0: "-1" wraps to 18446744073709551615 for an unsigned option, an overflow saturates, and
// "010" is octal 8; this refuses all of those, and fractions and exponents ("1.5", "1e23"), before
// conversion. Every integer option of every command has one (CommandLine adds it where a
// declaration has none).
inline CLI::Validator integer_range(std::int64_t min, std::int64_t max) {
  const std::string range = fmt::format("[{}, {}]", min, max);
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        const std::size_t sign = !text.empty() && (text[0] == '-' || text[0] == '+') ? 1 : 0;
        const std::string digits = text.substr(sign);
        if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos)
          return fmt::format("'{}' is not an integer (expected a whole decimal number in {})", text, range);
        if (digits.size() > 1 && digits[0] == '0')
          return fmt::format("'{}': an integer is written without leading zeros (expected a number in {})", text, range);
        std::int64_t v = 0;
        const std::string signed_digits = (text[0] == '-' ? "-" : "") + digits;
        const auto [end, ec] = std::from_chars(signed_digits.data(), signed_digits.data() + signed_digits.size(), v);
        if (ec != std::errc() || v < min || v > max)
          return fmt::format("{} is out of range: expected an integer in {}", text, range);
        return {};
      },
      "in " + range, "INTEGER_RANGE");
}

// A usage error (exit code 2) for checks that involve several options.
[[noreturn]] inline void usage_error(const std::string& message) { throw CLI::ValidationError(message); }

// Runs a library's validate() (which throws Error naming the setting) as a usage error.
template <class Validate>
void check_as_usage(Validate&& validate) {
  try {
    validate();
  } catch (const Error& e) {
    usage_error(e.what());
  }
}

// Where the command line (command_line.hpp) keeps each command's checks that involve several
// options. They must see every value, from the command line and from --config alike, so they
// cannot live in a command's parse_complete_callback: CLI11 runs that as soon as the command's own
// arguments are parsed, before the root's --config is read.
class OptionCheckRegistry {
 public:
  virtual ~OptionCheckRegistry() = default;
  void add_checks(const CLI::App* cmd, std::function<void()> checks) { checks_[cmd].push_back(std::move(checks)); }
  void run_checks(const CLI::App* cmd) const {
    if (const auto it = checks_.find(cmd); it != checks_.end())
      for (const auto& check : it->second) check();
  }

 private:
  std::map<const CLI::App*, std::vector<std::function<void()>>> checks_;
};

// Registers checks of `cmd` (a subcommand of the CommandLine) that run once all of its options are
// converted and validated and before its callback: a failed one throws a usage error.
inline void add_option_checks(CLI::App* cmd, std::function<void()> checks) {
  auto* registry = dynamic_cast<OptionCheckRegistry*>(cmd->get_parent());
  if (registry == nullptr) throw std::logic_error("add_option_checks: " + cmd->get_name() + " is not a command of a CommandLine");
  registry->add_checks(cmd, std::move(checks));
}

// --feature-size WIDTHxHEIGHT of the simulated encoder: each side in [1, kMaxFeatureSide] and one
// feature map (dim values of bytes_per_value per pixel) at most kMaxFeatureMapBytes. Every command
// with a simulated encoder checks it here. Returns {width, height}.
inline std::pair<int, int> check_simulated_feature_size(const std::string& feature_size, int dim, int bytes_per_value) {
  static const std::regex kSize(R"(([1-9]\d{0,4})[xX]([1-9]\d{0,4}))");
  std::smatch m;
  if (!std::regex_match(feature_size, m, kSize))
    usage_error(fmt::format("--feature-size '{}' is not WIDTHxHEIGHT (e.g. 192x128)", feature_size));
  const int w = std::stoi(m[1]), h = std::stoi(m[2]);
  if (w > bounds::kMaxFeatureSide || h > bounds::kMaxFeatureSide)
    usage_error(fmt::format("--feature-size {}: each side must be in [1, {}]", feature_size, bounds::kMaxFeatureSide));
  const double bytes = static_cast<double>(bytes_per_value) * w * h * dim;
  if (bytes > bounds::kMaxFeatureMapBytes)
    usage_error(fmt::format("--feature-size {} with --dim {} makes {:.0f} MB feature maps; at most {:.0f} MB",
                            feature_size, dim, bytes / 1e6, bounds::kMaxFeatureMapBytes / 1e6));
  return {w, h};
}

// Rough memory of a map per 100 m driven, from measurements on the simulated OS1-64 sequence
// (100 m at 0.25 m: 46 MB of occupancy and 23 500 semantic voxels; both grow like
// voxel_size^-2.3, measured between 0.5 m and 0.125 m). Real scenes differ by a small factor.
inline double estimated_map_megabytes_per_100m(double voxel_size, int dim, int bytes_per_value) {
  const double scale = std::pow(0.25 / voxel_size, 2.3);
  const double semantic_bytes = 23'500.0 * (static_cast<double>(dim) * bytes_per_value + 40.0);
  return scale * (46.0 + semantic_bytes / 1e6);
}

}  // namespace slamvdb::cli
