#include "slamvdb/map/occupancy_grid.hpp"

#include <fmt/format.h>
#include <xmmintrin.h>

#include <limits>

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
