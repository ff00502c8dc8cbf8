#pragma once
// Checks of the mapping commands (`map`, `slam`) that involve several options, run once all options
// are read (command line and --config) and before the sequence is: a bad combination, or one that
// cannot fit in memory, is a usage error (exit code 2) naming the options.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <array>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "memory_checks.hpp"
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

// --fusion-weighting of the mapping commands (map, slam): the rule is recorded in the map.
inline void add_fusion_weighting_option(CLI::App* cmd, std::string& rule) {
  cmd->add_option("--fusion-weighting", rule,
                  "How the views of a voxel are combined: 'paper' is the paper's plain running mean (Eq. 6.1); "
                  "'quality' weights each view by its range, incidence angle and distance to the image border and "
                  "leaves out pixels near depth edges (not yet shown to beat 'paper'); 'single-view' is a baseline "
                  "that keeps only each voxel's nearest view. Recorded in the map")
      ->capture_default_str()
      ->check(CLI::IsMember(std::vector<std::string>(kFusionRuleNames.begin(), kFusionRuleNames.end())));
}

// The rule named by --fusion-weighting in `p`, with the map setting the single-view baseline needs.
inline void set_fusion_weighting(PipelineOptions& p, const std::string& rule) {
  p.fusion.weighting = fusion_weighting_from_string(rule);
  p.map.semantic.single_view = p.fusion.weighting == FusionWeighting::kSingleView;
}

// What a mapping command (map, slam) was asked for beyond PipelineOptions, as given.
struct MappingChoices {
  std::string features = "simulated";  // simulated, model, precomputed or none
  std::string feature_size = "192x128";
  std::string sim_feature_precision = "fp32";  // the simulated encoder's output values (their size bounds a feature map)
  std::string precision = "fp16";              // embeddings at rest
  std::string distortion;
  double max_memory_gb = 0;  // 0: the memory available on this machine
};

// The checks every mapping command shares (map, slam; `p.map.semantic.dim` is the embedding
// dimension), once all options are read: usage errors (exit code 2) naming the options.
inline void check_map_options(const PipelineOptions& p, const MappingChoices& c) {
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
  if (p.map.semantic.dim < 1 || p.map.semantic.dim > bounds::kMaxDim)
    usage_error(fmt::format("--dim {}: expected an integer in [1, {}]", p.map.semantic.dim, bounds::kMaxDim));
  if (!c.distortion.empty()) parse_distortion_option(c.distortion);
  if (c.features == "simulated")
    check_simulated_feature_size(c.feature_size, p.map.semantic.dim, c.sim_feature_precision == "fp16" ? 2 : 4);
  check_scan_memory(occ, c.features == "none" ? 0 : p.map.semantic.dim, c.max_memory_gb);
  if (occ.voxel_size < 0.1) {
    const int value_bytes = c.precision == "fp32" ? 4 : 2;
    spdlog::warn("--voxel-size {} m: expect roughly {:.0f} MB of map memory per 100 m driven (about 50 MB at 0.25 m; "
                 "memory grows like voxel size^-2.3)",
                 occ.voxel_size, estimated_map_megabytes_per_100m(occ.voxel_size, p.map.semantic.dim, value_bytes));
  }
}

// --max-memory of the mapping commands.
inline void add_max_memory_option(CLI::App* cmd, double& max_memory_gb) {
  cmd->add_option("--max-memory", max_memory_gb,
                  "Refuse to start when one LiDAR scan is estimated to need more memory than this (GB); 0: the memory "
                  "available on this machine (MemAvailable, or less under a cgroup limit)")
      ->capture_default_str()
      ->check(finite_range(0, 1e6));
}

}  // namespace slamvdb::cli
