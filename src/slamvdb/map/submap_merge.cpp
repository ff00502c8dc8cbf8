#include "slamvdb/map/submap_merge.hpp"

#include <absl/container/flat_hash_map.h>

#include <algorithm>
#include <cmath>

namespace slamvdb {
namespace {

// Where a voxel of a map placed at T_dst_src lands on a grid of cells of `cell_size`.
template <class Key>
struct Resampler {
  Pose T_dst_src;
  double src_voxel_size, inv_cell_size;
  bool inside(const VoxelKey& k) const {
    return in_grid_extent(T_dst_src * center_of_key(k, src_voxel_size) * inv_cell_size);
  }
  Key operator()(const VoxelKey& k) const {
    return key_of_point<Key>(T_dst_src * center_of_key(k, src_voxel_size), inv_cell_size);
  }
};

struct SourceCell {
  float log_odds = -std::numeric_limits<float>::infinity();  // max over the source voxels
  uint64_t count = 0;
  VoxelStatistics stats;    // combined (weights summed, spreads by Chan's rule)
  std::vector<float> mean;  // weight-weighted, when count > 0
};

}  // namespace

double occupied_overlap(const VoxelMap& target, const VoxelMap& source, const Pose& T_target_source) {
  const std::size_t n_target = target.occupancy().num_occupied_voxels();
  const std::size_t n_source = source.occupancy().num_occupied_voxels();
  if (n_target == 0 || n_source == 0) return 0.0;
  const Resampler<VoxelKey> to_target{T_target_source, source.voxel_size(), 1.0 / target.voxel_size()};
  absl::flat_hash_map<VoxelKey, bool> landed;  // distinct target voxels hit, counted once
  source.occupancy().for_each_occupied([&](const VoxelKey& k, float) {
    if (!to_target.inside(k)) return;
    const VoxelKey t = to_target(k);
    landed.try_emplace(t, target.occupancy().is_occupied(t));
  });
  std::size_t both = 0;
  for (const auto& [k, occupied] : landed) both += occupied;
  return static_cast<double>(both) / static_cast<double>(std::min(n_target, n_source));
}

MergeReport merge_into(VoxelMap& target, const VoxelMap& source, const Pose& T_target_source) {
  MergeReport report;
  const auto dim = static_cast<std::size_t>(target.semantics().dim());
  const OccupancyParams& op = target.occupancy().params();
  report.target_known_before = target.occupancy().num_known_voxels();
  report.semantic_entries_before = target.semantics().size() + source.semantics().size();
  target.semantics().for_each([&](SemanticLayer::Handle h) { report.counts_before += target.semantics().count_of(h); });
  source.semantics().for_each([&](SemanticLayer::Handle h) { report.counts_before += source.semantics().count_of(h); });

  // 1. Resample the source onto the target grid.
  const Resampler<VoxelKey> to_target{T_target_source, source.voxel_size(), 1.0 / target.voxel_size()};
  absl::flat_hash_map<VoxelKey, SourceCell> cells;
  std::vector<float> embedding(dim);
  source.occupancy().for_each_known([&](const VoxelKey& k, float lo) {
    ++report.source_known;
    if (!to_target.inside(k)) return;
    SourceCell& c = cells[to_target(k)];
    c.log_odds = std::max(c.log_odds, lo);
    const auto h = source.semantics().find(k);
    if (!h) return;
    const uint32_t n = source.semantics().count_of(*h);
    const VoxelStatistics st = source.semantics().statistics_of(*h);
    source.semantics().read(*h, embedding.data());
    if (c.mean.empty()) c.mean.assign(dim, 0.0f);
    if (source.semantics().params().single_view) {  // the baseline keeps its best observation
      if (c.count == 0 || st.weight > c.stats.weight) c.mean = embedding, c.stats = st;
    } else {
      const double total = static_cast<double>(c.stats.weight) + static_cast<double>(st.weight);
      const float w = static_cast<float>(total > 0 ? static_cast<double>(st.weight) / total
                                                   : static_cast<double>(n) / static_cast<double>(c.count + n));
      const float d2 = kernels::running_mean_sq(c.mean.data(), embedding.data(), w, dim);
      c.stats = c.count == 0 ? st : combine_statistics(c.stats, st, d2);
    }
    c.count += n;
  });

  // 2. Combine with the target, in key order so that the result does not depend on hash order.
  std::vector<std::pair<VoxelKey, SourceCell*>> order;
  order.reserve(cells.size());
  for (auto& [k, c] : cells) order.emplace_back(k, &c);
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  OccupancyGrid& grid = target.occupancy();
  SemanticLayer& layer = target.semantics();
  for (const auto& [k, c] : order) {
    const std::optional<float> before = grid.log_odds(k);
    const float lo = before ? std::clamp(*before + c->log_odds, op.clamp_min, op.clamp_max) : c->log_odds;
    grid.set_log_odds(k, lo);
    if (c->count > 0)
      layer.accumulate(k, c->mean.data(), static_cast<uint32_t>(std::min<uint64_t>(c->count, UINT32_MAX)), c->stats);
    if (lo < op.occupied_threshold) {  // a semantic entry needs a surface; say what is dropped
      if (const auto h = layer.find(k)) {
        report.counts_dropped_free += layer.count_of(*h);
        ++report.entries_dropped_free;
        layer.erase(k);
      }
    }
  }
  report.target_known_after = grid.num_known_voxels();
  report.semantic_entries_after = layer.size();
  layer.for_each([&](SemanticLayer::Handle h) { report.counts_after += layer.count_of(h); });
  report.merged = true;
  return report;
}

std::vector<WorldOccupancyCell> combine_occupancy(const std::vector<PlacedVoxelMap>& submaps, double cell_size,
                                                  const OccupancyParams& params) {
  absl::flat_hash_map<IndexCellKey, float> world;
  absl::flat_hash_map<IndexCellKey, float> own;  // one submap's cells: max of its voxels in each
  for (const PlacedVoxelMap& s : submaps) {
    own.clear();
    const Resampler<IndexCellKey> to_world{s.T_world_submap, s.voxels->voxel_size(), 1.0 / cell_size};
    s.voxels->occupancy().for_each_known([&](const VoxelKey& k, float lo) {
      if (!to_world.inside(k)) return;
      const auto [it, inserted] = own.try_emplace(to_world(k), lo);
      if (!inserted) it->second = std::max(it->second, lo);
    });
    for (const auto& [cell, lo] : own) {
      const auto [it, inserted] = world.try_emplace(cell, lo);
      if (!inserted) it->second = std::clamp(it->second + lo, params.clamp_min, params.clamp_max);
    }
  }
  std::vector<WorldOccupancyCell> out;
  out.reserve(world.size());
  for (const auto& [cell, lo] : world) out.push_back({cell, lo});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.cell < b.cell; });
  return out;
}

}  // namespace slamvdb
