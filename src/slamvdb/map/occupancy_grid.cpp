#include "slamvdb/map/occupancy_grid.hpp"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <xmmintrin.h>

#include <atomic>
#include <limits>
#include <numeric>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

void OccupancyParams::validate() const {
  auto fail = [](const std::string& what) { throw Error("invalid occupancy parameters: " + what); };
  if (!(voxel_size > 0) || !std::isfinite(voxel_size)) fail(fmt::format("voxel size {} must be > 0", voxel_size));
  if (!(log_odds_hit > 0)) fail("hit log-odds must be > 0");
  if (!(log_odds_miss < 0)) fail("miss log-odds must be < 0");
  if (!(clamp_min < occupied_threshold && occupied_threshold < clamp_max))
    fail("need clamp_min < occupied_threshold < clamp_max");
  if (!(min_point_range >= 0 && min_point_range < max_point_range)) fail("need 0 <= min range < max range");
  if (!(max_clearing_range >= 0)) fail("max clearing range must be >= 0");
}

ScanIntegrationStats& ScanIntegrationStats::operator+=(const ScanIntegrationStats& o) {
  points += o.points;
  dropped_nonfinite += o.dropped_nonfinite;
  dropped_no_return += o.dropped_no_return;
  dropped_too_close += o.dropped_too_close;
  dropped_out_of_extent += o.dropped_out_of_extent;
  beyond_max_range += o.beyond_max_range;
  hit_updates += o.hit_updates;
  miss_updates += o.miss_updates;
  voxels_freed += o.voxels_freed;
  return *this;
}

OccupancyGrid::Block::Block() { cells.fill({std::numeric_limits<float>::quiet_NaN(), 0}); }

OccupancyGrid::OccupancyGrid(const OccupancyParams& params) : params_(params) {
  params_.validate();
  inv_voxel_size_ = 1.0 / params_.voxel_size;
}

OccupancyGrid::Block& OccupancyGrid::block_at(const BlockKey& block_key) {
  auto& slot = blocks_[block_key];
  if (!slot) {
    slot = std::make_unique<Block>();
    regions_[region_of(block_key)].emplace_back(block_key, slot.get());
  }
  return *slot;
}

// Per-thread state of one scan's integration.
struct OccupancyGrid::ScanContext {
  ScanIntegrationStats stats;
  std::vector<VoxelKey> freed;
  std::vector<uint32_t> deferred;  // rays that reached a block that does not exist yet
};

void OccupancyGrid::set_occupied_bit(Block& b, int i, bool occupied) {
  std::atomic_ref<uint64_t> word(b.occupied_bits[i >> 6]);
  const uint64_t mask = uint64_t{1} << (i & 63);
  occupied ? word.fetch_or(mask, std::memory_order_relaxed) : word.fetch_and(~mask, std::memory_order_relaxed);
  std::atomic_ref<int>(b.num_occupied).fetch_add(occupied ? 1 : -1, std::memory_order_relaxed);
}

namespace {
// Population count without the POPCNT instruction (not in baseline x86-64; the compiler's builtin
// then calls a slow library routine).
inline int popcount64(uint64_t x) {
  x = x - ((x >> 1) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
  return static_cast<int>((x * 0x0101010101010101ULL) >> 56);
}
}  // namespace

// Called only by the thread that claimed the voxel's stamp for this scan, so the cell is ours.
void OccupancyGrid::update_voxel(Block& b, const VoxelKey& key, int i, float delta, ScanContext& ctx) {
  float& lo = b.cells[i].log_odds;
  const bool was_occupied = !std::isnan(lo) && lo >= params_.occupied_threshold;
  lo = std::clamp(std::isnan(lo) ? delta : lo + delta, params_.clamp_min, params_.clamp_max);
  const bool now_occupied = lo >= params_.occupied_threshold;
  if (now_occupied != was_occupied) {
    set_occupied_bit(b, i, now_occupied);
    if (was_occupied) {
      ++ctx.stats.voxels_freed;
      ctx.freed.push_back(key);
    }
  }
  ++(delta > 0 ? ctx.stats.hit_updates : ctx.stats.miss_updates);
}

ScanIntegrationStats OccupancyGrid::integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_grid_sensor,
                                                   std::vector<VoxelKey>* freed) {
  ScanIntegrationStats stats;
  stats.points = points_sensor.size();
  const Vec3d origin = T_grid_sensor.translation();
  const Eigen::Matrix3d R = T_grid_sensor.linear();
  if (!T_grid_sensor.matrix().allFinite() || !in_extent(origin))
    throw Error(fmt::format("sensor pose ({}, {}, {}) is outside the map's representable extent (+-{:.3g} m at "
                            "{} m voxels) or not finite",
                            origin.x(), origin.y(), origin.z(), kMaxGridCoordinate * params_.voxel_size,
                            params_.voxel_size));
  const uint32_t scan = ++scan_counter_;

  struct Ray {
    Vec3d dir;     // unit, world frame
    double range;  // metres
    bool hit;      // endpoint inserted as occupied
  };
  std::vector<Ray> rays;
  rays.reserve(points_sensor.size());
  for (const Vec3f& p : points_sensor) {
    if (!p.allFinite()) {
      ++stats.dropped_nonfinite;
      continue;
    }
    const double range = p.cast<double>().norm();
    if (range == 0.0) {
      ++stats.dropped_no_return;
      continue;
    }
    if (range < params_.min_point_range) {
      ++stats.dropped_too_close;
      continue;
    }
    const bool hit = range <= params_.max_point_range;
    const Vec3d dir = R * (p.cast<double>() / range);
    const double length = hit ? range : params_.max_point_range;
    // Both ends of what the ray touches must be representable: the end point (a hit) and the end
    // of the cleared segment.
    if (!in_extent(origin + dir * length) || !in_extent(origin + dir * std::min(length, params_.max_clearing_range))) {
      ++stats.dropped_out_of_extent;
      continue;
    }
    if (!hit) ++stats.beyond_max_range;
    rays.push_back({dir, length, hit});
  }

  // Rays are cast in parallel. A voxel is updated only by the thread that moves its stamp to this
  // scan (at most one update per voxel per scan). The block table is read-only while threads run:
  // a ray that needs a new block is deferred; its blocks are created serially and it is cast
  // again, skipping the voxels it already stamped, so a replay never updates a voxel twice.
  tbb::enumerable_thread_specific<ScanContext> contexts;
  const Vec3d from = origin * inv_voxel_size_;

  // serial = false: defer the ray at a missing block; serial = true: create blocks as needed.
  auto cast = [&](const Ray& r, uint32_t ray_index, bool hits, ScanContext& ctx, bool serial) {
    BlockKey cached_key(std::numeric_limits<int>::min(), 0, 0);
    Block* block = nullptr;
    bool stop = false;
    auto visit = [&](const VoxelKey& key, float delta) {
      if (stop) return;
      const BlockKey bk = block_of(key);
      if (!block || bk != cached_key) {
        if (serial) {
          block = &block_at(bk);
        } else {
          const auto it = blocks_.find(bk);
          if (it == blocks_.end()) {
            ctx.deferred.push_back(ray_index);
            stop = true;
            return;
          }
          block = it->second.get();
        }
        cached_key = bk;
      }
      const int i = index_in_block(key);
      uint32_t& stamp = block->cells[i].stamp;
      if (std::atomic_ref<uint32_t>(stamp).load(std::memory_order_relaxed) == scan) return;
      if (std::atomic_ref<uint32_t>(stamp).exchange(scan, std::memory_order_relaxed) == scan) return;
      update_voxel(*block, key, i, delta, ctx);
    };
    if (hits) {
      if (r.hit) visit(key_of(origin + r.dir * r.range), params_.log_odds_hit);
      return;
    }
    const double clear = std::min(r.range, params_.max_clearing_range);
    if (clear > 0)
      traverse_voxels(from, (origin + r.dir * clear) * inv_voxel_size_,
                      [&](const VoxelKey& k) { visit(k, params_.log_odds_miss); });
  };

  // Creates the blocks a ray crosses: the same DDA at block resolution, an eighth of the steps.
  auto create_blocks = [&](const Ray& r, bool hits) {
    if (hits) {
      block_at(block_of(key_of(origin + r.dir * r.range)));
      return;
    }
    const double clear = std::min(r.range, params_.max_clearing_range);
    const Vec3d to = (origin + r.dir * clear) * inv_voxel_size_ / kBlockSide;
    traverse_voxels<BlockKey>(from / kBlockSide, to, [&](const BlockKey& bk) { block_at(bk); });
    block_at(key_of_point<BlockKey>(to, 1.0));
  };

  // Hits first, all of them, so a voxel that is both an end point and on another ray counts as a
  // hit (OctoMap's rule: the free set excludes the occupied set).
  std::vector<uint32_t> todo(rays.size()), deferred;
  for (const bool hits : {true, false}) {
    todo.resize(rays.size());
    std::iota(todo.begin(), todo.end(), 0u);
    for (int round = 0; !todo.empty(); ++round) {
      if (round == 2) {  // rounding at block corners can still miss a block: finish serially
        ScanContext& ctx = contexts.local();
        for (uint32_t i : todo) cast(rays[i], i, hits, ctx, true);
        break;
      }
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, todo.size(), 512),
                        [&](const tbb::blocked_range<std::size_t>& range) {
                          ScanContext& ctx = contexts.local();
                          for (std::size_t j = range.begin(); j != range.end(); ++j)
                            cast(rays[todo[j]], todo[j], hits, ctx, false);
                        });
      deferred.clear();
      for (ScanContext& ctx : contexts) {
        deferred.insert(deferred.end(), ctx.deferred.begin(), ctx.deferred.end());
        ctx.deferred.clear();
      }
      for (uint32_t i : deferred) create_blocks(rays[i], hits);
      todo.swap(deferred);
    }
  }
  for (const ScanContext& ctx : contexts) {
    stats += ctx.stats;
    if (freed) freed->insert(freed->end(), ctx.freed.begin(), ctx.freed.end());
  }
  return stats;
}

std::optional<float> OccupancyGrid::log_odds(const VoxelKey& k) const {
  const auto it = blocks_.find(block_of(k));
  if (it == blocks_.end()) return std::nullopt;
  const float v = it->second->cells[index_in_block(k)].log_odds;
  if (std::isnan(v)) return std::nullopt;
  return v;
}

bool OccupancyGrid::is_occupied(const VoxelKey& k) const {
  const auto it = blocks_.find(block_of(k));
  return it != blocks_.end() && it->second->occupied(index_in_block(k));
}

void OccupancyGrid::set_log_odds(const VoxelKey& k, float value) {
  Block& b = block_at(block_of(k));
  const int i = index_in_block(k);
  b.cells[i].log_odds = value;
  const bool occ = !std::isnan(value) && value >= params_.occupied_threshold;
  if (occ != b.occupied(i)) set_occupied_bit(b, i, occ);
}

int OccupancyGrid::set_block(const BlockKey& key, const float* log_odds) {
  auto& slot = blocks_[key];
  if (!slot) {  // every cell is written below: no need to mark them unknown first
    slot = std::make_unique<Block>(Block::Uninitialized{});
    regions_[region_of(key)].emplace_back(key, slot.get());
  }
  Block& b = *slot;
  for (int i = 0; i < kBlockVoxels; ++i) b.cells[i] = {log_odds[i], 0};
  // Occupied and known bits four voxels at a time (SSE2, every x86-64): a comparison with NaN is
  // false, so unknown voxels are neither occupied nor known.
  const __m128 threshold = _mm_set1_ps(params_.occupied_threshold);
  int occupied = 0, known = 0;
  for (int w = 0; w < kBlockVoxels / 64; ++w) {
    uint64_t bits = 0, known_bits = 0;
    for (int j = 0; j < 64; j += 4) {
      const __m128 v = _mm_loadu_ps(log_odds + 64 * w + j);
      bits |= static_cast<uint64_t>(_mm_movemask_ps(_mm_cmpge_ps(v, threshold))) << j;
      known_bits |= static_cast<uint64_t>(_mm_movemask_ps(_mm_cmpord_ps(v, v))) << j;
    }
    b.occupied_bits[w] = bits;
    occupied += popcount64(bits);
    known += popcount64(known_bits);
  }
  b.num_occupied = occupied;
  return known;
}

std::size_t OccupancyGrid::num_known_voxels() const {
  std::size_t n = 0;
  for (const auto& [bk, b] : blocks_)
    for (const Cell& c : b->cells) n += !std::isnan(c.log_odds);
  return n;
}

std::size_t OccupancyGrid::num_occupied_voxels() const {
  std::size_t n = 0;
  for (const auto& [bk, b] : blocks_) n += static_cast<std::size_t>(b->num_occupied);
  return n;
}

std::size_t OccupancyGrid::memory_bytes() const {
  return blocks_.size() * sizeof(Block) + blocks_.capacity() * (sizeof(BlockMap::value_type) + 1);
}

}  // namespace slamvdb
