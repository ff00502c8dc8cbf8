#pragma once
// Whether a mapping run can finish on this machine, decided before any work: options inside their
// documented ranges can still ask for more memory than there is (`map --voxel-size 0.01` takes
// about 20 GB after one scan). The estimate is of the map after its first LiDAR scan, which no run
// can avoid; a longer drive needs more (the per-100 m warning of map_option_checks.hpp).
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>

#include "option_checks.hpp"
#include "slamvdb/map/occupancy_grid.hpp"

namespace slamvdb::cli {

// The scan the estimate assumes: the largest the project's datasets have (RELLIS-3D's OS1-64 at
// 2048 columns; the SIMULATED one has 1024), beams over +-16.6 degrees of elevation.
inline constexpr double kEstimateRaysPerScan = 64.0 * 2048.0;
inline constexpr double kEstimateHalfElevationDeg = 16.6;
// Fitted to the blocks the SIMULATED drive's first scan creates (defaults but the voxel size):
// 18 900, 103 700, 403 700 and 1 196 000 blocks at 0.1, 0.05, 0.03 and 0.02 m; the model below
// gives 17 900, 102 000, 397 000 and 1 213 000.
inline constexpr double kSceneFactor = 0.21;   // share of the field of view the rays cross before they stop
inline constexpr double kGroundWeight = 7.9;   // the ground's surface, in blocks per (block edge)^2
inline constexpr double kRayLengthShare = 0.55;  // mean clearing length / clearing range (13.7 of 25 m)
// Resident memory over the grid's own bytes (hash table, allocator, the scan's working memory):
// 1.13 at 0.02 m and 1.30 at 0.03 m, measured.
inline constexpr double kResidentFactor = 1.2;

struct ScanMemoryEstimate {
  double occupancy_blocks = 0;
  double occupancy_bytes = 0;
  double semantic_bytes = 0;
  double total_bytes() const { return occupancy_bytes + semantic_bytes; }
};

// The map's memory after one scan. Occupancy: clearing rays create the 8^3-voxel blocks they cross
// up to min(max-clearing-range, max-range): a share of the blocks in the beams' field of view
// (the rays are denser than the blocks there down to about 0.01 m voxels) plus the ground's
// surface, and never more than the rays cross (1.5 blocks per block edge of path, the mean over
// directions). Semantic layer: at most one new entry per return a camera sees (under half of
// them), dim values accumulated in fp32 in the active submap.
inline ScanMemoryEstimate estimate_scan_memory(const OccupancyParams& occupancy, int dim) {
  const double block = kBlockSide * occupancy.voxel_size;
  const double reach = std::min(occupancy.max_clearing_range, occupancy.max_point_range);
  const double solid_angle = 4.0 * std::numbers::pi * std::sin(kEstimateHalfElevationDeg * std::numbers::pi / 180.0);
  const double volume_blocks = solid_angle * std::pow(reach / block, 3) / 3.0;
  const double ground_blocks = 2.0 * std::numbers::pi * std::pow(reach / block, 2);
  const double ray_blocks = kRayLengthShare * 1.5 * kEstimateRaysPerScan * reach / block;
  ScanMemoryEstimate e;
  e.occupancy_blocks = std::min(kSceneFactor * (volume_blocks + kGroundWeight * ground_blocks), ray_blocks);
  e.occupancy_bytes = e.occupancy_blocks * sizeof(OccupancyGrid::Block) * kResidentFactor;
  e.semantic_bytes = kEstimateRaysPerScan / 2 * (4.0 * dim + 48.0);
  return e;
}

// A number from a "Key:   N kB" line of /proc/meminfo, in bytes.
inline std::optional<double> meminfo_bytes(const std::string& key) {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key + ":", 0) != 0) continue;
    std::istringstream fields(line.substr(key.size() + 1));
    double kb = 0;
    if (fields >> kb) return kb * 1024.0;
  }
  return std::nullopt;
}

// Memory this process can still take: MemAvailable (free memory plus what the kernel can reclaim),
// or less if the cgroup (container) limit leaves less.
inline double available_memory_bytes() {
  double available = 0;
  if (const auto m = meminfo_bytes("MemAvailable")) available = *m;
  else available = static_cast<double>(::sysconf(_SC_AVPHYS_PAGES)) * static_cast<double>(::sysconf(_SC_PAGESIZE));
  std::ifstream max_file("/sys/fs/cgroup/memory.max"), current_file("/sys/fs/cgroup/memory.current");
  double limit = 0, current = 0;
  if (max_file >> limit && current_file >> current) available = std::min(available, std::max(0.0, limit - current));
  return available;
}

// Usage error (exit code 2) with the estimate when one scan would need more memory than
// `max_memory_gb` (0: what is available now).
inline void check_scan_memory(const OccupancyParams& occupancy, int dim, double max_memory_gb) {
  const ScanMemoryEstimate e = estimate_scan_memory(occupancy, dim);
  const bool machine = max_memory_gb <= 0;
  const double limit = machine ? available_memory_bytes() : max_memory_gb * 1e9;
  if (e.total_bytes() <= limit) return;
  usage_error(fmt::format(
      "--voxel-size {} m with --max-clearing-range {} m: one LiDAR scan of {:.0f} rays is estimated to take {:.1f} GB "
      "({:.2g} occupancy blocks of 8^3 voxels, {:.1f} GB; semantic layer {:.1f} GB), more than the {:.1f} GB {}; raise "
      "the voxel size, lower the clearing range, or set --max-memory if the estimate is wrong for your data",
      occupancy.voxel_size, occupancy.max_clearing_range, kEstimateRaysPerScan, e.total_bytes() / 1e9,
      e.occupancy_blocks, e.occupancy_bytes / 1e9, e.semantic_bytes / 1e9, limit / 1e9,
      machine ? "available on this machine" : "of --max-memory"));
}

}  // namespace slamvdb::cli
