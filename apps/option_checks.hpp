#pragma once
// Checks of numeric command-line options, shared by the subcommands: every value is validated
// before any work starts, and a bad one is a usage error (exit code 2) naming the option.
// CLI::Range alone is not enough for floating-point options: NaN compares false with both
// bounds and slips through, so finite_range() refuses NaN and inf explicitly.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdint>
#include <string>

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

// An integer in [min, max] (refuses fractions and out-of-range values before conversion).
inline CLI::Validator integer_range(std::int64_t min, std::int64_t max) {
  const std::string range = fmt::format("[{}, {}]", min, max);
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        std::int64_t v = 0;
        if (!CLI::detail::lexical_cast(text, v)) return fmt::format("'{}' is not an integer", text);
        if (v < min || v > max) return fmt::format("{} is out of range: expected an integer in {}", text, range);
        return {};
      },
      "in " + range, "INTEGER_RANGE");
}

// A usage error (exit code 2) for checks that involve several options.
[[noreturn]] inline void usage_error(const std::string& message) { throw CLI::ValidationError(message); }

// Rough memory of a map per 100 m driven, from measurements on the simulated OS1-64 sequence
// (100 m at 0.25 m: 46 MB of occupancy and 23 500 semantic voxels; both grow like
// voxel_size^-2.3, measured between 0.5 m and 0.125 m). Real scenes differ by a small factor.
inline double estimated_map_megabytes_per_100m(double voxel_size, int dim, int bytes_per_value) {
  const double scale = std::pow(0.25 / voxel_size, 2.3);
  const double semantic_bytes = 23'500.0 * (static_cast<double>(dim) * bytes_per_value + 40.0);
  return scale * (46.0 + semantic_bytes / 1e6);
}

}  // namespace slamvdb::cli
