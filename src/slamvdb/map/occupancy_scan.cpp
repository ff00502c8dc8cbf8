// OccupancyGrid::integrate_scan and its phases: preparing the rays, sorting them, casting them,
// and the bitmap update pass.
#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <span>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/map/occupancy_grid.hpp"
#include "slamvdb/map/occupancy_raycast.hpp"
#include "slamvdb/map/occupancy_rays.hpp"

namespace slamvdb {

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

// Called only by the thread that claimed the voxel's stamp for this scan, so the cell is ours. The
// caller counts the update (a counter in memory incremented per voxel made each update wait for
// the previous one).
void OccupancyGrid::update_voxel(Block& b, const BlockKey& bk, int i, float delta, ScanContext& ctx) {
  float& lo = b.cells[i].log_odds;
  const bool was_occupied = !std::isnan(lo) && lo >= params_.occupied_threshold;
  lo = std::clamp(std::isnan(lo) ? delta : lo + delta, params_.clamp_min, params_.clamp_max);
  const bool now_occupied = lo >= params_.occupied_threshold;
  if (now_occupied != was_occupied) [[unlikely]] {
    set_occupied_bit(b, i, now_occupied);
    if (was_occupied) {
      ++ctx.stats.voxels_freed;
      ctx.freed.push_back(voxel_of(bk, i));
    }
  }
}

// One scan's state, shared by the phases of integrate_scan.
//
// One update per voxel per scan: a voxel is updated only by the thread that moves its stamp to
// this scan. The block table is read-only while threads run: voxels of missing blocks are
// collected and updated serially once their blocks exist.
//
// Within the cube that the clearing range reaches around the sensor (occupancy_raycast.hpp),
// hits and misses are only marked, one bit per voxel, each thread in its own bitmaps (no atomics
// in the hot loops): most of a scan's ~10^7 ray crossings are of voxels an earlier ray crossed
// already, and a bit stays in cache where the cells (8 bytes, spread over blocks) do not. An
// update pass then visits every voxel marked in any of them once, in parallel over blocks, so no
// two threads touch the same voxel and the result is exactly the union of the rays whatever the
// threads. A voxel that is both an end point and on another ray counts as a hit (OctoMap's rule:
// the free set excludes the occupied set). When the clearing range needs a cube larger than
// RayCube allows, rays update cells directly instead, all hits before any miss.
struct OccupancyGrid::ScanPass {
  struct Marks {
    PooledBitmap words;      // misses, then hits (cube.num_words() each)
    Eigen::Vector3i lo, hi;  // bounding box of what was marked
  };

  ScanPass(OccupancyGrid& grid, const Pose& T_grid_sensor, uint32_t scan);
  ScanPass(const ScanPass&) = delete;  // `marks` creates bitmaps through `this`
  ScanPass& operator=(const ScanPass&) = delete;

  Block* find_block(const BlockKey& bk) {
    if (Block** s = window.slot(bk)) return *s;
    const auto it = grid.blocks_.find(bk);
    return it == grid.blocks_.end() ? nullptr : it->second.get();
  }
  void update(Block& b, const VoxelKey& key, float delta, ScanContext& ctx) {
    const int i = index_in_block(key);
    uint32_t& stamp = b.cells[i].stamp;
    if (std::atomic_ref<uint32_t>(stamp).load(std::memory_order_relaxed) == scan) return;
    if (std::atomic_ref<uint32_t>(stamp).exchange(scan, std::memory_order_relaxed) == scan) return;
    grid.update_voxel(b, block_of(key), i, delta, ctx);
    ++(delta > 0 ? ctx.stats.hit_updates : ctx.stats.miss_updates);
  }
  void apply_pending(std::vector<VoxelKey> ScanContext::*list, float delta);

  // The phases, in order.
  void prepare_rays(const std::vector<Vec3f>& points_sensor, Vec3d* rays, std::vector<uint32_t>& sort_keys);
  void cast_rays(const Vec3d* rays, const std::vector<uint32_t>& order);
  void update_marked_voxels();
  void add_results(ScanIntegrationStats& stats, std::vector<VoxelKey>* freed) const;

  OccupancyGrid& grid;
  const OccupancyParams& params;
  const uint32_t scan;
  const Vec3d origin;
  const Eigen::Matrix3d R;
  const Vec3d from;  // the sensor, cell units
  const VoxelKey from_key;
  const int reach;  // clearing rays stay within `reach` voxels of the sensor's voxel
  BlockWindow window;
  tbb::enumerable_thread_specific<ScanContext> contexts;
  const RayCube cube;
  const bool use_bitmap;
  // Per scan, not per thread: a thread's bitmap could be reused by a scan of another map that this
  // thread picks up while it waits inside ours.
  tbb::enumerable_thread_specific<Marks> marks;
};

OccupancyGrid::ScanPass::ScanPass(OccupancyGrid& grid, const Pose& T_grid_sensor, uint32_t scan)
    : grid(grid),
      params(grid.params_),
      scan(scan),
      origin(T_grid_sensor.translation()),
      R(T_grid_sensor.linear()),
      from(origin * grid.inv_voxel_size_),
      from_key(key_of_point<VoxelKey>(from, 1.0)),
      reach(static_cast<int>(std::ceil(params.max_clearing_range * grid.inv_voxel_size_)) + 1),
      cube(RayCube::around(from_key, reach)),
      use_bitmap(cube.side_bits != 0),
      marks([this] { return Marks{PooledBitmap(use_bitmap ? 2 * cube.num_words() : 0), from_key, from_key}; }) {
  constexpr int kMaxWindowHalf = 32;  // 65^3 blocks: 2 MB of pointers
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
        const auto it = grid.regions_.find(RegionKey(x, y, z));
        if (it == grid.regions_.end()) continue;
        for (const auto& [bk, block] : it->second)
          if (Block** s = window.slot(bk)) *s = block;
      }
}

void OccupancyGrid::ScanPass::apply_pending(std::vector<VoxelKey> ScanContext::*list, float delta) {
  ScanContext& mine = contexts.local();
  for (ScanContext& ctx : contexts) {
    for (const VoxelKey& k : ctx.*list) {
      const BlockKey bk = block_of(k);
      Block* b = find_block(bk);
      if (!b) {
        b = &grid.block_at(bk);
        if (Block** s = window.slot(bk)) *s = b;
      }
      update(*b, k, delta, mine);
    }
    (ctx.*list).clear();
  }
}

// Rays are prepared (occupancy_rays.hpp) and the hits outside the cube applied in parallel.
void OccupancyGrid::ScanPass::prepare_rays(const std::vector<Vec3f>& points_sensor, Vec3d* rays,
                                           std::vector<uint32_t>& sort_keys) {
  const RaySetup setup{.R = R,
                       .origin = origin,
                       .inv_voxel_size = grid.inv_voxel_size_,
                       .min_range = params.min_point_range,
                       .max_range = params.max_point_range,
                       .clear_range = params.max_clearing_range,
                       .from_key = from_key,
                       .cube = cube};
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_sensor.size(), 2048), [&](const tbb::blocked_range<std::size_t>& rr) {
    ScanContext& ctx = contexts.local();
    Marks& m = marks.local();
    PreparedRays out(from_key);
    slamvdb::prepare_rays(setup, std::span<const Vec3f>(points_sensor.data() + rr.begin(), rr.size()), rays + rr.begin(),
                          sort_keys.data() + rr.begin(), use_bitmap ? m.words.data() + cube.num_words() : nullptr, out);
    ScanIntegrationStats& st = ctx.stats;
    st.dropped_nonfinite += out.nonfinite, st.dropped_no_return += out.no_return, st.dropped_too_close += out.too_close;
    st.dropped_out_of_extent += out.out_of_extent, st.beyond_max_range += out.beyond_max_range;
    m.lo = m.lo.cwiseMin(out.lo), m.hi = m.hi.cwiseMax(out.hi);
    for (const VoxelKey& k : out.hits_outside) {
      if (Block* b = find_block(block_of(k))) update(*b, k, params.log_odds_hit, ctx);
      else ctx.pending.push_back(k);
    }
  });
}

// Eight rays at a time, in casting order (casting_order), marking the bitmaps or, without them,
// updating the cells.
void OccupancyGrid::ScanPass::cast_rays(const Vec3d* rays, const std::vector<uint32_t>& order) {
  const auto num_cast = static_cast<uint32_t>(order.size());
  const float miss = params.log_odds_miss;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, (num_cast + 7) / 8, 64), [&](const tbb::blocked_range<uint32_t>& gr) {
    const uint32_t first = gr.begin() * 8, last = std::min(num_cast, gr.end() * 8);
    const std::span<const uint32_t> segment(order.data() + first, last - first);
    if (use_bitmap) {
      mark_segments(cube, from, rays, segment, marks.local().words.data());
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
    for (const uint32_t i : segment) traverse_voxels(from, rays[i], visit);
  });
}

// The update pass over every thread's bitmaps (use_bitmap only), then the hits in blocks that did
// not exist yet.
void OccupancyGrid::ScanPass::update_marked_voxels() {
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
  const float hit = params.log_odds_hit, miss = params.log_odds_miss;
  // A brick's marks, read (and cleared) one brick ahead of its update so that its cells can be
  // prefetched: the cells are spread over blocks of 4 kB, and waiting for them was most of the pass.
  struct MarkedBrick {
    BlockKey bk;
    Block* block = nullptr;
    uint64_t hits[8], misses[8];
  };
  tbb::parallel_for(tbb::blocked_range<int>(0, ny * nz, 1), [&](const tbb::blocked_range<int>& rows) {
    ScanContext& ctx = contexts.local();
    std::size_t hit_updates = 0, miss_updates = 0;
    auto update_brick = [&](const MarkedBrick& b) {
      // The only update of these voxels in this scan: no other thread has this block.
      auto apply = [&](int i, float delta, std::vector<VoxelKey>& pending) {
        if (!b.block) return pending.push_back(voxel_of(b.bk, i));  // counted when applied
        b.block->cells[i].stamp = scan;
        grid.update_voxel(*b.block, b.bk, i, delta, ctx);
      };
      for (int z = 0; z < 8; ++z) {
        const uint64_t missed = b.misses[z] & ~b.hits[z];
        if (b.block) hit_updates += std::popcount(b.hits[z]), miss_updates += std::popcount(missed);
        for (uint64_t bits = b.hits[z]; bits; bits &= bits - 1)
          apply((z << 6) | __builtin_ctzll(bits), hit, ctx.pending_hits);  // the voxel's index in its block
        for (uint64_t bits = missed; bits; bits &= bits - 1)
          apply((z << 6) | __builtin_ctzll(bits), miss, ctx.pending);
      }
    };
    MarkedBrick bricks[2];
    int ahead = 0;  // bricks[ahead] is read, not yet updated
    bool waiting = false;
    for (int row = rows.begin(); row != rows.end(); ++row) {
      const std::size_t row_first = (static_cast<std::size_t>(blo.z() + row / ny) << (2 * cube.side_bits)) |
                                    (static_cast<std::size_t>(blo.y() + row % ny) << cube.side_bits);
      for (int bx = blo.x(); bx < blo.x() + nx; ++bx) {
        const std::size_t brick = row_first | static_cast<std::size_t>(bx);
        MarkedBrick& b = bricks[ahead ^ waiting];
        uint64_t any = 0;
        for (int z = 0; z < 8; ++z) b.hits[z] = b.misses[z] = 0;
        for (uint64_t* m : maps)
          for (int z = 0; z < 8; ++z) {
            b.misses[z] |= std::exchange(m[brick * 8 + z], 0);
            b.hits[z] |= std::exchange(m[hits_at + brick * 8 + z], 0);
          }
        for (int z = 0; z < 8; ++z) any |= b.misses[z] | b.hits[z];
        if (!any) continue;
        b.bk = cube.block_of_brick(brick);
        b.block = find_block(b.bk);
        if (b.block)
          for (int z = 0; z < 8; ++z) {
            // One bit per eight voxels (a cache line of cells) with any mark.
            uint64_t lines = b.misses[z] | b.hits[z];
            lines |= lines >> 4, lines |= lines >> 2, lines |= lines >> 1;
            for (lines &= 0x0101010101010101u; lines; lines &= lines - 1)
              __builtin_prefetch(&b.block->cells[(z << 6) | __builtin_ctzll(lines)], 1);
          }
        if (waiting) update_brick(bricks[ahead]), ahead ^= 1;
        waiting = true;
      }
    }
    if (waiting) update_brick(bricks[ahead]);
    ctx.stats.hit_updates += hit_updates, ctx.stats.miss_updates += miss_updates;
  });
  for (Marks& m : marks) {  // where finished lanes and rays without a hit wrote
    std::fill_n(m.words.data() + hits_at - 8, 8, 0);
    std::fill_n(m.words.data() + 2 * hits_at - 8, 8, 0);
    m.words.set_clear();
  }
  apply_pending(&ScanContext::pending_hits, hit);
}

void OccupancyGrid::ScanPass::add_results(ScanIntegrationStats& stats, std::vector<VoxelKey>* freed) const {
  for (const ScanContext& ctx : contexts) {
    stats += ctx.stats;
    if (freed) freed->insert(freed->end(), ctx.freed.begin(), ctx.freed.end());
  }
}

ScanIntegrationStats OccupancyGrid::integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_grid_sensor,
                                                   std::vector<VoxelKey>* freed) {
  const Vec3d origin = T_grid_sensor.translation();
  if (!T_grid_sensor.matrix().allFinite() || !in_extent(origin))
    throw Error(fmt::format("sensor pose ({}, {}, {}) is outside the map's representable extent (+-{:.3g} m at "
                            "{} m voxels) or not finite",
                            origin.x(), origin.y(), origin.z(), kMaxGridCoordinate * params_.voxel_size,
                            params_.voxel_size));
  ScanPass pass(*this, T_grid_sensor, ++scan_counter_);

  // End of each ray's cleared segment, cell units; not zeroed (megabytes, each written before read).
  std::unique_ptr<Vec3d[]> rays(new Vec3d[points_sensor.size()]);
  std::vector<uint32_t> sort_keys(points_sensor.size());
  pass.prepare_rays(points_sensor, rays.get(), sort_keys);
  pass.apply_pending(&ScanContext::pending, params_.log_odds_hit);

  pass.cast_rays(rays.get(), casting_order(sort_keys));
  if (pass.use_bitmap) pass.update_marked_voxels();
  pass.apply_pending(&ScanContext::pending, params_.log_odds_miss);

  ScanIntegrationStats stats;
  stats.points = points_sensor.size();
  pass.add_results(stats, freed);
  return stats;
}

}  // namespace slamvdb
