#pragma once
// Sparse, unbounded log-odds occupancy grid (OctoMap's update rule on a hashed grid of 8^3 blocks).
#include <absl/container/flat_hash_map.h>
#include <absl/hash/hash.h>

#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/keys.hpp"

namespace slamvdb {

struct OccupancyParams {
  double voxel_size = 0.25;
  float log_odds_hit = 0.8472979f;    // logit(0.7), OctoMap's default
  float log_odds_miss = -0.4054651f;  // logit(0.4)
  float clamp_min = -2.0f;            // logit(0.1192)
  float clamp_max = 3.5f;             // logit(0.971)
  float occupied_threshold = 0.0f;    // logit(0.5); occupied when log-odds >= this
  double min_point_range = 0.3;       // closer returns hit the robot itself
  double max_point_range = 100.0;     // beyond: the ray still clears, the return is not inserted
  double max_clearing_range = 25.0;   // misses only along the first metres of each ray
  void validate() const;              // throws Error
};

// What one scan did; every dropped point is counted under its reason.
struct ScanIntegrationStats {
  std::size_t points = 0;
  std::size_t dropped_nonfinite = 0;   // NaN or Inf coordinates
  std::size_t dropped_no_return = 0;   // exactly at the sensor origin (how Ouster marks no return)
  std::size_t dropped_too_close = 0;   // closer than min_point_range
  std::size_t dropped_out_of_extent = 0;  // the ray would leave the representable grid (keys.hpp)
  std::size_t beyond_max_range = 0;    // cleared up to max_point_range, not inserted as a hit
  std::size_t hit_updates = 0;         // voxels updated as occupied
  std::size_t miss_updates = 0;        // voxels updated as free
  std::size_t voxels_freed = 0;        // occupied -> free transitions
  std::size_t dropped() const {
    return dropped_nonfinite + dropped_no_return + dropped_too_close + dropped_out_of_extent;
  }
  ScanIntegrationStats& operator+=(const ScanIntegrationStats& o);
};

class OccupancyGrid {
 public:
  // A voxel's log-odds and the last scan that updated it sit side by side: ray casting reads both.
  struct Cell {
    float log_odds;  // NaN = never observed
    uint32_t stamp;  // last scan that updated the voxel (one update per scan)
  };
  struct Block {
    Block();  // every voxel unknown
    struct Uninitialized {};
    explicit Block(Uninitialized) {}
    bool occupied(int i) const { return (occupied_bits[i >> 6] >> (i & 63)) & 1u; }
    std::array<Cell, kBlockVoxels> cells;
    std::array<uint64_t, kBlockVoxels / 64> occupied_bits{};  // written atomically during a scan
    int num_occupied = 0;
  };
  using BlockMap = absl::flat_hash_map<BlockKey, std::unique_ptr<Block>>;

  explicit OccupancyGrid(const OccupancyParams& params = {});

  // Inserts one scan given in the sensor frame; the grid's own frame is called "grid" (a submap's
  // frame when the grid belongs to one). Keys of voxels that turned free are appended to `freed`
  // (the semantic layer drops them). Throws Error when the sensor origin lies outside the
  // representable extent; rays that would leave it are dropped and counted.
  ScanIntegrationStats integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_grid_sensor,
                                      std::vector<VoxelKey>* freed = nullptr);

  const OccupancyParams& params() const { return params_; }
  double voxel_size() const { return params_.voxel_size; }
  // p in the grid frame (metres), inside the extent (in_extent).
  VoxelKey key_of(const Vec3d& p) const { return key_of_point<VoxelKey>(p, inv_voxel_size_); }
  bool in_extent(const Vec3d& p) const { return in_grid_extent(p * inv_voxel_size_); }
  Vec3d center_of(const VoxelKey& k) const { return center_of_key(k, params_.voxel_size); }

  std::optional<float> log_odds(const VoxelKey& k) const;  // nullopt when never observed
  bool is_occupied(const VoxelKey& k) const;
  // Sets a voxel's log-odds directly (merging, tests); NaN makes it unknown again.
  void set_log_odds(const VoxelKey& k, float value);
  // Sets a whole block (map loading): kBlockVoxels log-odds, NaN for unknown. Returns how many of
  // them are known.
  int set_block(const BlockKey& key, const float* log_odds);

  std::size_t num_blocks() const { return blocks_.size(); }
  std::size_t num_known_voxels() const;
  std::size_t num_occupied_voxels() const;
  std::size_t memory_bytes() const;
  uint32_t scans_integrated() const { return scan_counter_; }

  const BlockMap& blocks() const { return blocks_; }

  // f(block_key, block) for every block within `radius` of `center` (grid frame, metres), found through
  // the region index, so the cost depends on the neighbourhood, not on the size of the map.
  template <class F>
  void for_each_block_near(const Vec3d& center, double radius, F&& f) const {
    const double region_side = kBlockSide * (1 << kRegionBits) * params_.voxel_size;
    const Eigen::Vector3i lo = ((center.array() - radius) / region_side).floor().cast<int>();
    const Eigen::Vector3i hi = ((center.array() + radius) / region_side).floor().cast<int>();
    for (int x = lo.x(); x <= hi.x(); ++x)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int z = lo.z(); z <= hi.z(); ++z) {
          const auto it = regions_.find(RegionKey(x, y, z));
          if (it == regions_.end()) continue;
          for (const auto& [bk, block] : it->second) f(bk, *block);
        }
  }

  template <class F>  // f(const VoxelKey&, float log_odds) for every known voxel
  void for_each_known(F&& f) const {
    for (const auto& [bk, block] : blocks_)
      for (int i = 0; i < kBlockVoxels; ++i)
        if (!std::isnan(block->cells[i].log_odds)) f(voxel_of(bk, i), block->cells[i].log_odds);
  }

  template <class F>  // f(const VoxelKey&, float log_odds)
  void for_each_occupied(F&& f) const {
    for (const auto& [bk, block] : blocks_) {
      if (block->num_occupied == 0) continue;
      for (int i = 0; i < kBlockVoxels; ++i)
        if (block->occupied(i)) f(voxel_of(bk, i), block->cells[i].log_odds);
    }
  }

 private:
  // integrate_scan's parts (occupancy_scan.cpp).
  struct ScanContext;
  struct BlockWindow;
  struct ScanPass;
  Block& block_at(const BlockKey& block_key);
  void set_occupied_bit(Block& b, int index, bool occupied);
  void update_voxel(Block& b, const BlockKey& bk, int index, float delta, ScanContext& ctx);

  // Blocks grouped by region (8^3 blocks, 16 m at 0.25 m voxels) for neighbourhood queries.
  using Region = std::vector<std::pair<BlockKey, Block*>>;

  OccupancyParams params_;
  double inv_voxel_size_;
  BlockMap blocks_;
  absl::flat_hash_map<RegionKey, Region> regions_;
  uint32_t scan_counter_ = 0;
};

// Visits the cells a segment crosses, from the one containing `from` up to (excluding) the one
// containing `to` (3D DDA, Amanatides & Woo 1987). Coordinates in cell units, inside the extent
// (keys.hpp), so that no step overflows.
template <class Key = VoxelKey, class Visit>
void traverse_voxels(const Vec3d& from, const Vec3d& to, Visit&& visit) {
  // Scalars rather than indexed arrays: this loop runs millions of times per scan and indexed
  // stack arrays keep the state in memory instead of registers.
  int kx = static_cast<int>(std::floor(from.x())), ky = static_cast<int>(std::floor(from.y())),
      kz = static_cast<int>(std::floor(from.z()));
  const int ex = static_cast<int>(std::floor(to.x())), ey = static_cast<int>(std::floor(to.y())),
            ez = static_cast<int>(std::floor(to.z()));
  constexpr double kInf = std::numeric_limits<double>::infinity();
  auto setup = [](double f, double d, int k, int& step, double& t_max, double& t_delta) {
    if (d > 0) {
      step = 1, t_delta = 1.0 / d, t_max = (k + 1 - f) * t_delta;
    } else if (d < 0) {
      step = -1, t_delta = -1.0 / d, t_max = (f - k) * t_delta;
    } else {
      step = 0, t_delta = kInf, t_max = kInf;
    }
  };
  int sx, sy, sz;
  double tx, ty, tz, dx, dy, dz;
  setup(from.x(), to.x() - from.x(), kx, sx, tx, dx);
  setup(from.y(), to.y() - from.y(), ky, sy, ty, dy);
  setup(from.z(), to.z() - from.z(), kz, sz, tz, dz);
  // The exact number of steps is the Manhattan distance between the end keys; bounding the loop
  // by it keeps rounding at voxel corners from ever running past the end voxel.
  int remaining = std::abs(ex - kx) + std::abs(ey - ky) + std::abs(ez - kz);
  while (remaining-- > 0) {
    visit(Key(kx, ky, kz));
    if (tx < ty) {
      if (tx < tz) kx += sx, tx += dx;
      else kz += sz, tz += dz;
    } else {
      if (ty < tz) ky += sy, ty += dy;
      else kz += sz, tz += dz;
    }
  }
}

}  // namespace slamvdb
