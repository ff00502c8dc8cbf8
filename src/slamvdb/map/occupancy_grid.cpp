#include "slamvdb/map/occupancy_grid.hpp"

#include <fmt/format.h>

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
  beyond_max_range += o.beyond_max_range;
  hit_updates += o.hit_updates;
  miss_updates += o.miss_updates;
  voxels_freed += o.voxels_freed;
  return *this;
}

OccupancyGrid::Block::Block() {
  log_odds.fill(std::numeric_limits<float>::quiet_NaN());
  stamp.fill(0);
}

OccupancyGrid::OccupancyGrid(const OccupancyParams& params) : params_(params) {
  params_.validate();
  inv_voxel_size_ = 1.0 / params_.voxel_size;
}

OccupancyGrid::Block& OccupancyGrid::block_at(const VoxelKey& block_key) {
  auto& slot = blocks_[block_key];
  if (!slot) slot = std::make_unique<Block>();
  return *slot;
}

void OccupancyGrid::update_voxel(Block& b, const VoxelKey& key, int i, float delta, ScanIntegrationStats& stats,
                                 std::vector<VoxelKey>* freed) {
  float& lo = b.log_odds[i];
  const bool was_occupied = b.occupied[i];
  const float v = std::isnan(lo) ? delta : lo + delta;
  lo = std::clamp(v, params_.clamp_min, params_.clamp_max);
  const bool now_occupied = lo >= params_.occupied_threshold;
  if (now_occupied != was_occupied) {
    b.occupied[i] = now_occupied;
    b.num_occupied += now_occupied ? 1 : -1;
    if (was_occupied) {
      ++stats.voxels_freed;
      if (freed) freed->push_back(key);
    }
  }
}

ScanIntegrationStats OccupancyGrid::integrate_scan(const std::vector<Vec3f>& points_sensor, const Pose& T_world_sensor,
                                                   std::vector<VoxelKey>* freed) {
  ScanIntegrationStats stats;
  stats.points = points_sensor.size();
  const uint32_t scan = ++scan_counter_;
  const Vec3d origin = T_world_sensor.translation();
  const Eigen::Matrix3d R = T_world_sensor.linear();

  // Classify every point first: rays need the direction, hits need the end point.
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
    if (!hit) ++stats.beyond_max_range;
    rays.push_back({R * (p.cast<double>() / range), hit ? range : params_.max_point_range, hit});
  }

  // Hits first and stamped, so a voxel that is both an end point and on some other ray is updated
  // once, as occupied (OctoMap's rule: the free set excludes the occupied set).
  VoxelKey cached_block_key(std::numeric_limits<int>::min(), 0, 0);
  Block* cached = nullptr;
  auto visit = [&](const VoxelKey& key, float delta) {
    const VoxelKey bk = block_key_of(key);
    if (!cached || bk != cached_block_key) {
      cached = &block_at(bk);
      cached_block_key = bk;
    }
    const int i = index_in_block(key);
    if (cached->stamp[i] == scan) return;
    cached->stamp[i] = scan;
    update_voxel(*cached, key, i, delta, stats, freed);
    ++(delta > 0 ? stats.hit_updates : stats.miss_updates);
  };
  for (const Ray& r : rays)
    if (r.hit) visit(key_of(origin + r.dir * r.range), params_.log_odds_hit);

  const Vec3d from = origin * inv_voxel_size_;
  for (const Ray& r : rays) {
    const double clear = std::min(r.range, params_.max_clearing_range);
    if (clear <= 0) continue;
    traverse_voxels(from, (origin + r.dir * clear) * inv_voxel_size_,
                    [&](const VoxelKey& k) { visit(k, params_.log_odds_miss); });
  }
  return stats;
}

std::optional<float> OccupancyGrid::log_odds(const VoxelKey& k) const {
  const auto it = blocks_.find(block_key_of(k));
  if (it == blocks_.end()) return std::nullopt;
  const float v = it->second->log_odds[index_in_block(k)];
  if (std::isnan(v)) return std::nullopt;
  return v;
}

bool OccupancyGrid::is_occupied(const VoxelKey& k) const {
  const auto it = blocks_.find(block_key_of(k));
  return it != blocks_.end() && it->second->occupied[index_in_block(k)];
}

void OccupancyGrid::set_log_odds(const VoxelKey& k, float value) {
  Block& b = block_at(block_key_of(k));
  const int i = index_in_block(k);
  b.log_odds[i] = value;
  const bool occ = !std::isnan(value) && value >= params_.occupied_threshold;
  if (occ != b.occupied[i]) {
    b.occupied[i] = occ;
    b.num_occupied += occ ? 1 : -1;
  }
}

std::size_t OccupancyGrid::num_known_voxels() const {
  std::size_t n = 0;
  for (const auto& [bk, b] : blocks_)
    for (float v : b->log_odds) n += !std::isnan(v);
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
