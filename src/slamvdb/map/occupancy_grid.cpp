#include "slamvdb/map/occupancy_grid.hpp"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <limits>
#include <numeric>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/map/occupancy_raycast.hpp"

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
  std::vector<VoxelKey> pending;       // voxels of blocks that do not exist yet (created serially)
  std::vector<VoxelKey> pending_hits;  // the same for hits marked in the bitmap
};

// Pointers to the blocks of the cube around the sensor that clearing rays reach, so that casting
// finds a block by indexing instead of hashing (a hash lookup costs more than the DDA steps a ray
// takes inside one block). nullptr: the block does not exist yet. Blocks outside it are hashed.
struct OccupancyGrid::BlockWindow {
  BlockKey lo;
  int side = 0;
  std::vector<Block*> slots;
  Block** slot(const BlockKey& b) {
    const auto x = static_cast<unsigned>(b.x() - lo.x()), y = static_cast<unsigned>(b.y() - lo.y()),
               z = static_cast<unsigned>(b.z() - lo.z());
    const auto n = static_cast<unsigned>(side);
    return x < n && y < n && z < n ? &slots[(z * n + y) * n + x] : nullptr;
  }
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

  // Rays are grouped by direction: the cells of a cube map around the sensor, kTiles x kTiles per
  // face (about 5.6 degrees at 16).
  constexpr int kTiles = 16;
  auto tile_of = [](const Vec3d& d) {
    const Vec3d a = d.cwiseAbs();
    const int face = a.x() >= a.y() && a.x() >= a.z() ? 0 : (a.y() >= a.z() ? 1 : 2);
    const double m = 1.0 / a[face], u = d[(face + 1) % 3] * m, v = d[(face + 2) % 3] * m;
    const int iu = std::min(kTiles - 1, static_cast<int>((u + 1) * (kTiles / 2))),
              iv = std::min(kTiles - 1, static_cast<int>((v + 1) * (kTiles / 2)));
    return static_cast<uint32_t>(((2 * face + (d[face] < 0)) * kTiles + iu) * kTiles + iv);
  };
  const Vec3d from = origin * inv_voxel_size_;
  const VoxelKey from_key = key_of_point<VoxelKey>(from, 1.0);
  // Clearing rays stay within `reach` voxels of the sensor's voxel.
  const int reach = static_cast<int>(std::ceil(params_.max_clearing_range * inv_voxel_size_)) + 1;
  constexpr int kMaxWindowHalf = 32;  // 65^3 blocks: 2 MB of pointers
  BlockWindow window;
  {
    const int half = std::min(kMaxWindowHalf, (reach + kBlockSide - 1) / kBlockSide + 1);
    const BlockKey center = block_of(from_key);
    window.lo = BlockKey(center.x() - half, center.y() - half, center.z() - half);
    window.side = 2 * half + 1;
    window.slots.assign(static_cast<std::size_t>(window.side) * window.side * window.side, nullptr);
    const RegionKey rlo = region_of(window.lo);
    const int last = window.side - 1;
    const RegionKey rhi = region_of(BlockKey(window.lo.x() + last, window.lo.y() + last, window.lo.z() + last));
    for (int x = rlo.x(); x <= rhi.x(); ++x)
      for (int y = rlo.y(); y <= rhi.y(); ++y)
        for (int z = rlo.z(); z <= rhi.z(); ++z) {
          const auto it = regions_.find(RegionKey(x, y, z));
          if (it == regions_.end()) continue;
          for (const auto& [bk, block] : it->second)
            if (Block** s = window.slot(bk)) *s = block;
        }
  }
  auto find_block = [&](const BlockKey& bk) -> Block* {
    if (Block** s = window.slot(bk)) return *s;
    const auto it = blocks_.find(bk);
    return it == blocks_.end() ? nullptr : it->second.get();
  };

  // One update per voxel per scan: a voxel is updated only by the thread that moves its stamp to
  // this scan. The block table is read-only while threads run: voxels of missing blocks are
  // collected and updated serially once their blocks exist.
  tbb::enumerable_thread_specific<ScanContext> contexts;
  auto update = [&](Block& b, const VoxelKey& key, float delta, ScanContext& ctx) {
    const int i = index_in_block(key);
    uint32_t& stamp = b.cells[i].stamp;
    if (std::atomic_ref<uint32_t>(stamp).load(std::memory_order_relaxed) == scan) return;
    if (std::atomic_ref<uint32_t>(stamp).exchange(scan, std::memory_order_relaxed) == scan) return;
    update_voxel(b, key, i, delta, ctx);
  };
  auto apply_pending = [&](std::vector<VoxelKey> ScanContext::*list, float delta) {
    ScanContext& mine = contexts.local();
    for (ScanContext& ctx : contexts) {
      for (const VoxelKey& k : ctx.*list) {
        const BlockKey bk = block_of(k);
        Block* b = find_block(bk);
        if (!b) {
          b = &block_at(bk);
          if (Block** s = window.slot(bk)) *s = b;
        }
        update(*b, k, delta, mine);
      }
      (ctx.*list).clear();
    }
  };

  // Within the cube that the clearing range reaches around the sensor (occupancy_raycast.hpp),
  // hits and misses are only marked, one bit per voxel, each thread in its own bitmaps (no atomics
  // in the hot loops): most of a scan's ~10^7 ray crossings are of voxels an earlier ray crossed
  // already, and a bit stays in cache where the cells (8 bytes, spread over blocks) do not. An
  // update pass then visits every voxel marked in any of them once, in parallel over blocks, so no
  // two threads touch the same voxel and the result is exactly the union of the rays whatever the
  // threads. A voxel that is both an end point and on another ray counts as a hit (OctoMap's rule:
  // the free set excludes the occupied set). When the clearing range needs a cube larger than
  // RayCube allows, rays update cells directly instead, all hits before any miss.
  const RayCube cube = RayCube::around(from_key, reach);
  const bool use_bitmap = cube.side_bits != 0;
  struct Marks {
    PooledBitmap words;      // misses, then hits (cube.num_words() each)
    Eigen::Vector3i lo, hi;  // bounding box of what was marked
  };
  // Per scan, not per thread: a thread's bitmap could be reused by a scan of another map that this
  // thread picks up while it waits inside ours.
  tbb::enumerable_thread_specific<Marks> marks(
      [&] { return Marks{PooledBitmap(use_bitmap ? 2 * cube.num_words() : 0), from_key, from_key}; });

  // Rays are prepared and the hits outside the cube applied in parallel. A cast ray's sort key is
  // its tile, then its length in voxels (10 bits, saturated); dropped rays get kNoKey.
  constexpr uint32_t kNoTile = 6 * kTiles * kTiles, kNoKey = ~0u;
  // End of each ray's cleared segment, cell units; not zeroed (megabytes, each written before read).
  std::unique_ptr<Vec3d[]> rays(new Vec3d[points_sensor.size()]);
  std::vector<uint32_t> sort_keys(points_sensor.size());
  const double min_range2 = params_.min_point_range * params_.min_point_range,
               max_range2 = params_.max_point_range * params_.max_point_range,
               clear_range2 = params_.max_clearing_range * params_.max_clearing_range;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_sensor.size(), 2048), [&](const tbb::blocked_range<std::size_t>& rr) {
    ScanContext& ctx = contexts.local();
    ScanIntegrationStats& st = ctx.stats;
    Marks& m = marks.local();
    uint64_t* const hit_words = m.words.data() + (use_bitmap ? cube.num_words() : 0);
    for (std::size_t j = rr.begin(); j != rr.end(); ++j) {
      sort_keys[j] = kNoKey;
      const Vec3f& p = points_sensor[j];
      if (!p.allFinite()) {
        ++st.dropped_nonfinite;
        continue;
      }
      // Squared ranges against squared limits: the square root (and a division) only for the
      // rays that are cut short.
      const double range2 = p.cast<double>().squaredNorm();
      if (range2 == 0.0) {
        ++st.dropped_no_return;
        continue;
      }
      if (range2 < min_range2) {
        ++st.dropped_too_close;
        continue;
      }
      const bool hit = range2 <= max_range2;
      // R p scaled instead of a unit direction times a length.
      const Vec3d rp = R * p.cast<double>();
      Vec3d end, to;
      if (hit && range2 <= clear_range2) {
        end = to = (origin + rp) * inv_voxel_size_;
      } else {
        const double range = std::sqrt(range2);
        const double length = hit ? range : params_.max_point_range;
        end = hit ? Vec3d((origin + rp) * inv_voxel_size_) : Vec3d((origin + rp * (length / range)) * inv_voxel_size_);
        to = (origin + rp * (std::min(length, params_.max_clearing_range) / range)) * inv_voxel_size_;
      }
      // Both ends of what the ray touches must be representable: the end point (a hit) and the end
      // of the cleared segment.
      if (!in_grid_extent(end) || !in_grid_extent(to)) {
        ++st.dropped_out_of_extent;
        continue;
      }
      const VoxelKey to_key = key_of_point<VoxelKey>(to, 1.0);
      rays[j] = to;
      const auto steps = static_cast<uint32_t>((to_key - from_key).cwiseAbs().sum());
      sort_keys[j] = tile_of(rp) << 10 | std::min(steps, 1023u);
      m.lo = m.lo.cwiseMin(to_key), m.hi = m.hi.cwiseMax(to_key);
      if (!hit) {
        ++st.beyond_max_range;
        continue;
      }
      const VoxelKey k = to == end ? to_key : key_of_point<VoxelKey>(end, 1.0);
      if (use_bitmap && cube.contains(k)) {
        const uint32_t bit = cube.bit_of(k);
        hit_words[bit >> 6] |= uint64_t{1} << (bit & 63);
        m.lo = m.lo.cwiseMin(k), m.hi = m.hi.cwiseMax(k);
      } else if (Block* b = find_block(block_of(k))) {
        update(*b, k, params_.log_odds_hit, ctx);
      } else {
        ctx.pending.push_back(k);
      }
    }
  });
  apply_pending(&ScanContext::pending, params_.log_odds_hit);

  // Rays are cast grouped by direction (cube-map tiles) so that neighbouring rays mark
  // neighbouring words, and by length within a tile: they are cast eight at a time, for as many
  // steps as the longest of the eight needs (two stable counting sorts).
  // Not zeroed (every element is written): these are megabytes.
  std::unique_ptr<Vec3d[]> by_length;
  std::unique_ptr<uint32_t[]> by_length_tile;
  {
    constexpr uint32_t kBuckets = 1024;
    std::vector<uint32_t> first(kBuckets + 1, 0);
    for (const uint32_t k : sort_keys)
      if (k != kNoKey) ++first[(k & (kBuckets - 1)) + 1];
    std::partial_sum(first.begin(), first.end(), first.begin());
    by_length.reset(new Vec3d[first[kBuckets]]), by_length_tile.reset(new uint32_t[first[kBuckets]]);
    for (uint32_t i = 0; i < sort_keys.size(); ++i)
      if (const uint32_t k = sort_keys[i]; k != kNoKey) {
        const uint32_t at = first[k & (kBuckets - 1)]++;
        by_length[at] = rays[i], by_length_tile[at] = k >> 10;
      }
  }
  const auto num_cast = static_cast<uint32_t>(std::count_if(sort_keys.begin(), sort_keys.end(), [](uint32_t k) { return k != kNoKey; }));
  Vec3d* const ends = rays.get();  // the rays, sorted (their original order is no longer needed)
  {
    std::vector<uint32_t> next(kNoTile + 1, 0);
    for (uint32_t i = 0; i < num_cast; ++i) ++next[by_length_tile[i] + 1];
    std::partial_sum(next.begin(), next.end(), next.begin());
    for (uint32_t i = 0; i < num_cast; ++i) ends[next[by_length_tile[i]]++] = by_length[i];
  }
  const float miss = params_.log_odds_miss;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, (num_cast + 7) / 8, 64), [&](const tbb::blocked_range<uint32_t>& gr) {
    const uint32_t first = gr.begin() * 8, last = std::min(num_cast, gr.end() * 8);
    const std::span<const Vec3d> segment(ends + first, last - first);
    if (use_bitmap) {
      mark_segments(cube, from, segment, marks.local().words.data());
      return;
    }
    ScanContext& ctx = contexts.local();
    BlockKey cached_key(std::numeric_limits<int>::min(), 0, 0);
    Block* block = nullptr;
    auto visit = [&](const VoxelKey& k) {
      const BlockKey bk = block_of(k);
      if (bk != cached_key) cached_key = bk, block = find_block(bk);
      if (block) update(*block, k, miss, ctx);
      else ctx.pending.push_back(k);
    };
    for (const Vec3d& to : segment) traverse_voxels(from, to, visit);
  });

  if (use_bitmap) {
    // The bricks of the marked bounding box, two more voxels around it for rays that round off
    // past a corner at their end. The pass clears what it reads.
    std::vector<uint64_t*> maps;
    Eigen::Vector3i lo = from_key, hi = from_key;
    for (Marks& m : marks) {
      maps.push_back(m.words.data());
      lo = lo.cwiseMin(m.lo), hi = hi.cwiseMax(m.hi);
    }
    const int last = (1 << cube.side_bits) - 1;
    Eigen::Vector3i blo, bhi;
    for (int a = 0; a < 3; ++a) {
      blo[a] = std::clamp((lo[a] - 2 - cube.lo[a]) >> kBlockBits, 0, last);
      bhi[a] = std::clamp((hi[a] + 2 - cube.lo[a]) >> kBlockBits, 0, last);
    }
    const int nx = bhi.x() - blo.x() + 1, ny = bhi.y() - blo.y() + 1, nz = bhi.z() - blo.z() + 1;
    const std::size_t hits_at = cube.num_words();
    const float hit = params_.log_odds_hit;
    tbb::parallel_for(tbb::blocked_range<int>(0, ny * nz, 1), [&](const tbb::blocked_range<int>& rows) {
      ScanContext& ctx = contexts.local();
      for (int row = rows.begin(); row != rows.end(); ++row) {
        const std::size_t row_first = (static_cast<std::size_t>(blo.z() + row / ny) << (2 * cube.side_bits)) |
                                      (static_cast<std::size_t>(blo.y() + row % ny) << cube.side_bits);
        for (int bx = blo.x(); bx < blo.x() + nx; ++bx) {
          const std::size_t brick = row_first | static_cast<std::size_t>(bx);
          uint64_t hits[8] = {}, misses[8] = {}, any = 0;
          for (uint64_t* m : maps)
            for (int z = 0; z < 8; ++z) {
              misses[z] |= std::exchange(m[brick * 8 + z], 0);
              hits[z] |= std::exchange(m[hits_at + brick * 8 + z], 0);
            }
          for (int z = 0; z < 8; ++z) any |= misses[z] | hits[z];
          if (!any) continue;
          const BlockKey bk = cube.block_of_brick(brick);
          Block* const block = find_block(bk);
          // The only update of these voxels in this scan: no other thread has this block.
          auto apply = [&](int i, float delta, std::vector<VoxelKey>& pending) {
            if (!block) return pending.push_back(voxel_of(bk, i));
            block->cells[i].stamp = scan;
            update_voxel(*block, voxel_of(bk, i), i, delta, ctx);
          };
          for (int z = 0; z < 8; ++z) {
            for (uint64_t bits = hits[z]; bits; bits &= bits - 1)
              apply((z << 6) | __builtin_ctzll(bits), hit, ctx.pending_hits);  // the voxel's index in its block
            for (uint64_t bits = misses[z] & ~hits[z]; bits; bits &= bits - 1)
              apply((z << 6) | __builtin_ctzll(bits), miss, ctx.pending);
          }
        }
      }
    });
    for (Marks& m : marks) {  // where finished lanes wrote (occupancy_raycast.cpp)
      std::fill_n(m.words.data() + hits_at - 8, 8, 0);
      m.words.set_clear();
    }
    apply_pending(&ScanContext::pending_hits, hit);
  }
  apply_pending(&ScanContext::pending, miss);

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
