#pragma once
// Checks of `slamvdb map` that involve several options, run once all options are parsed and
// before the sequence is read: a bad combination is a usage error (exit code 2) naming the options.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <array>
#include <filesystem>
#include <regex>
#include <sstream>
#include <string>

#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"

namespace slamvdb::cli {

// Ray casting visits up to max-clearing-range / voxel-size voxels per ray, and fusion looks at
// every map region within max-depth: both grow with these ratios (cubically for fusion), so they
// are bounded, not only the ranges (at 0.25 m voxels: 1000 m; at 0.01 m: 40 m).
inline constexpr double kMaxRangeInVoxels = 4000.0;

// "k1 k2 p1 p2 k3": five finite numbers, nothing else.
inline std::array<double, 5> parse_distortion_option(const std::string& text) {
  std::istringstream in(text);
  std::array<double, 5> d{};
  std::string token;
  for (double& v : d) {
    if (!(in >> token) || !CLI::detail::lexical_cast(token, v) || !std::isfinite(v))
      usage_error(fmt::format("--distortion '{}' needs five finite numbers: k1 k2 p1 p2 k3", text));
  }
  if (in >> token) usage_error(fmt::format("--distortion '{}' has more than five numbers (k1 k2 p1 p2 k3)", text));
  return d;
}

// sim_feature_precision: the simulated encoder's output values, "fp32" or "fp16" (their size bounds
// a feature map's bytes).
inline void check_map_options(const PipelineOptions& p, const std::string& features, const std::string& feature_size,
                              const std::string& sim_feature_precision, const std::string& precision,
                              const std::string& distortion, const std::string& output) {
  const auto& occ = p.map.occupancy;
  if (!(occ.min_point_range < occ.max_point_range))
    usage_error(fmt::format("--min-range {} must be below --max-range {}", occ.min_point_range, occ.max_point_range));
  if (occ.max_clearing_range / occ.voxel_size > kMaxRangeInVoxels)
    usage_error(fmt::format("--max-clearing-range {} m is {:.0f} voxels of --voxel-size {} m; at most {:.0f} voxels per "
                            "ray are traced (lower the range or raise the voxel size)",
                            occ.max_clearing_range, occ.max_clearing_range / occ.voxel_size, occ.voxel_size,
                            kMaxRangeInVoxels));
  if (!(p.fusion.max_depth > p.fusion.min_depth))
    usage_error(fmt::format("--max-depth {} m must be above the fusion's minimum depth of {} m", p.fusion.max_depth,
                            p.fusion.min_depth));
  if (p.fusion.max_depth / occ.voxel_size > kMaxRangeInVoxels)
    usage_error(fmt::format("--max-depth {} m is {:.0f} voxels of --voxel-size {} m; fusion looks at most {:.0f} voxels "
                            "far (lower the depth or raise the voxel size)",
                            p.fusion.max_depth, p.fusion.max_depth / occ.voxel_size, occ.voxel_size, kMaxRangeInVoxels));
  if (!distortion.empty()) parse_distortion_option(distortion);
  if (features == "simulated") {
    static const std::regex kSize(R"((\d{1,5})[xX](\d{1,5}))");
    std::smatch m;
    if (!std::regex_match(feature_size, m, kSize))
      usage_error(fmt::format("--feature-size '{}' is not WIDTHxHEIGHT", feature_size));
    const int w = std::stoi(m[1]), h = std::stoi(m[2]);
    if (w < 1 || h < 1 || w > bounds::kMaxFeatureSide || h > bounds::kMaxFeatureSide)
      usage_error(fmt::format("--feature-size {}: each side must be in [1, {}]", feature_size, bounds::kMaxFeatureSide));
    const double bytes = (sim_feature_precision == "fp16" ? 2.0 : 4.0) * w * h * p.map.semantic.dim;
    if (bytes > bounds::kMaxFeatureMapBytes)
      usage_error(fmt::format("--feature-size {} with --dim {} makes {:.0f} MB feature maps; at most {:.0f} MB",
                              feature_size, p.map.semantic.dim, bytes / 1e6, bounds::kMaxFeatureMapBytes / 1e6));
  }
  // The output location is checked now, not after the whole replay.
  const std::filesystem::path dir = std::filesystem::absolute(output).parent_path();
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw Error(fmt::format("-o {}: directory {} does not exist", output, dir.string()));
  if (::access(dir.c_str(), W_OK) != 0)
    throw Error(fmt::format("-o {}: directory {} is not writable", output, dir.string()));
  if (occ.voxel_size < 0.1) {
    const int value_bytes = precision == "fp32" ? 4 : 2;
    spdlog::warn("--voxel-size {} m: expect roughly {:.0f} MB of map memory per 100 m driven (about 50 MB at 0.25 m; "
                 "memory grows like voxel size^-2.3)",
                 occ.voxel_size, estimated_map_megabytes_per_100m(occ.voxel_size, p.map.semantic.dim, value_bytes));
  }
}

}  // namespace slamvdb::cli
