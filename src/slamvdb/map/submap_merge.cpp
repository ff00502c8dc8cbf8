#include "slamvdb/map/submap_merge.hpp"

#include <absl/container/flat_hash_map.h>

#include <algorithm>
#include <array>
#include <limits>
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

// The same resampling as an affine map of the integer key, for combine_occupancy's hot loop:
// a voxel's coordinate on the destination grid, in cells, is A * k + b (A = R * voxel / cell,
// b = (R * voxel / 2 + t) / cell), in plain arithmetic (no Eigen temporaries: this runs once per
// known voxel, also under the sanitizers). Its rounding differs from the Resampler's (centre,
// then pose, then scale) by far less than kBoundaryGuard of a cell while the coordinates stay
// within kFastExtent cells (~1e-9 cell there), so wherever the coordinate is further than the
// guard from a cell boundary both floor to the same cell. Voxels near a boundary (a few in a
// million, or all of them on grids that line up exactly) and keys far out go through the
// Resampler itself: the cells are always the Resampler's.
class AffineCellResampler {
 public:
  AffineCellResampler(const Pose& T_dst_src, double src_voxel_size, double cell_size)
      : exact_{T_dst_src, src_voxel_size, 1.0 / cell_size} {
    const Eigen::Matrix3d A = T_dst_src.linear() * (src_voxel_size / cell_size);
    const Vec3d b = (T_dst_src.linear() * Vec3d::Constant(0.5 * src_voxel_size) + T_dst_src.translation()) / cell_size;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) a_[r][c] = A(r, c);
      b_[r] = b[r];
    }
    fast_ = b.cwiseAbs().maxCoeff() < kFastExtent;  // also false for NaN
  }

  // Whether k lands inside the representable extent, and where (as Resampler::inside, operator()).
  bool operator()(const VoxelKey& k, IndexCellKey& cell) const {
    if (fast_) {
      const double x = k.x(), y = k.y(), z = k.z();
      int out[3];
      bool clear = true;
      for (int r = 0; r < 3; ++r) {
        const double q = a_[r][0] * x + a_[r][1] * y + a_[r][2] * z + b_[r];
        if (!(std::abs(q) < kFastExtent)) {
          clear = false;
          break;
        }
        out[r] = floor_to_int(q);
        const double frac = q - out[r];  // in [0, 1)
        clear = clear && frac > kBoundaryGuard && frac < 1.0 - kBoundaryGuard;
      }
      if (clear) {
        cell = IndexCellKey(out[0], out[1], out[2]);
        return true;
      }
    }
    if (!exact_.inside(k)) return false;
    cell = exact_(k);
    return true;
  }

 private:
  static constexpr double kFastExtent = 1 << 20;  // cells
  static constexpr double kBoundaryGuard = 1e-6;  // cells
  Resampler<IndexCellKey> exact_;
  double a_[3][3], b_[3];
  bool fast_;
};

// Log-odds on the world grid kept in dense 8^3 blocks of cells (NaN: no value yet). A submap's
// voxels land in a few neighbouring blocks, so most of them find their cell through the block of
// the one before instead of a hash lookup, and the cells of a block share cache lines.
using CellBlockKey = GridKey<struct CellBlockKeyTag>;
class OccupancyCellBlocks {
 public:
  using Block = std::array<float, kBlockVoxels>;
  static CellBlockKey block_of_cell(const IndexCellKey& c) {
    return {c.x() >> kBlockBits, c.y() >> kBlockBits, c.z() >> kBlockBits};
  }
  static int index_of_cell(const IndexCellKey& c) { return index_in_block(VoxelKey(c.x(), c.y(), c.z())); }

  float& at(const IndexCellKey& c) {
    const CellBlockKey b = block_of_cell(c);
    if (last_ == nullptr || b != last_key_) {
      const auto [it, inserted] = index_.try_emplace(b, blocks_.size());
      if (inserted) blocks_.emplace_back(b, nan_block());
      last_key_ = b;
      last_ = &blocks_[it->second].second;
    }
    return (*last_)[index_of_cell(c)];
  }
  Block& block(const CellBlockKey& b) {
    last_ = nullptr;
    const auto [it, inserted] = index_.try_emplace(b, blocks_.size());
    if (inserted) blocks_.emplace_back(b, nan_block());
    return blocks_[it->second].second;
  }
  std::vector<std::pair<CellBlockKey, Block>>& blocks() { return blocks_; }
  void clear() {  // the next submap reuses the blocks' storage
    index_.clear();
    blocks_.clear();
    last_ = nullptr;
  }

 private:
  static Block nan_block() {
    Block b;
    b.fill(std::numeric_limits<float>::quiet_NaN());
    return b;
  }
  absl::flat_hash_map<CellBlockKey, std::size_t> index_;
  std::vector<std::pair<CellBlockKey, Block>> blocks_;
  CellBlockKey last_key_;
  Block* last_ = nullptr;
};

// Every known cell of `world`, sorted by key (z, then y, then x) without sorting the cells: the
// blocks sorted by key, then, layer of blocks (same block z) by layer, each cell z of the layer
// row of blocks (same block y) by row, each cell y of the row across the row's blocks in x order.
std::vector<WorldOccupancyCell> cells_in_key_order(std::vector<std::pair<CellBlockKey, OccupancyCellBlocks::Block>>& blocks) {
  std::sort(blocks.begin(), blocks.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<WorldOccupancyCell> out;
  std::size_t known = 0;
  for (const auto& [key, block] : blocks)
    for (const float lo : block) known += !std::isnan(lo);
  out.reserve(known);
  const auto same = [&](std::size_t a, std::size_t b, bool and_y) {
    return blocks[a].first.z() == blocks[b].first.z() && (!and_y || blocks[a].first.y() == blocks[b].first.y());
  };
  for (std::size_t layer = 0, layer_end; layer < blocks.size(); layer = layer_end) {
    for (layer_end = layer + 1; layer_end < blocks.size() && same(layer_end, layer, false);) ++layer_end;
    for (int z = 0; z < kBlockSide; ++z)
      for (std::size_t row = layer, row_end; row < layer_end; row = row_end) {
        for (row_end = row + 1; row_end < layer_end && same(row_end, row, true);) ++row_end;
        for (int y = 0; y < kBlockSide; ++y)
          for (std::size_t b = row; b < row_end; ++b)
            for (int x = 0; x < kBlockSide; ++x) {
              const float lo = blocks[b].second[index_in_block(VoxelKey(x, y, z))];
              if (std::isnan(lo)) continue;
              const CellBlockKey& k = blocks[b].first;
              out.push_back({IndexCellKey(k.x() * kBlockSide + x, k.y() * kBlockSide + y, k.z() * kBlockSide + z), lo});
            }
      }
  }
  return out;
}

struct SourceCell {
  float log_odds = -std::numeric_limits<float>::infinity();  // max over the source voxels
  uint64_t count = 0;
  VoxelStatistics stats;    // combined (weights summed, spreads by Chan's rule)
  int session = -1;         // the newest last-observed session of its entries
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

MergeReport merge_into(VoxelMap& target, const VoxelMap& source, const Pose& T_target_source,
                       const SessionOrder& sessions) {
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
    const int session = source.semantics().session_of(*h);
    c.session = c.session < 0 ? session : sessions.newest(c.session, session);
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
    if (c->count > 0) {
      const auto existing = layer.find(k);
      const int session = existing ? sessions.newest(layer.session_of(*existing), c->session) : c->session;
      layer.accumulate(k, c->mean.data(), static_cast<uint32_t>(std::min<uint64_t>(c->count, UINT32_MAX)), c->stats);
      layer.set_session(*layer.find(k), session);
    }
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
  OccupancyCellBlocks world;
  OccupancyCellBlocks own;  // one submap's cells: max of its voxels in each
  for (const PlacedVoxelMap& s : submaps) {
    own.clear();
    const AffineCellResampler to_world(s.T_world_submap, s.voxels->voxel_size(), cell_size);
    IndexCellKey cell;
    s.voxels->occupancy().for_each_known([&](const VoxelKey& k, float lo) {
      if (!to_world(k, cell)) return;
      float& c = own.at(cell);
      c = std::isnan(c) ? lo : std::max(c, lo);
    });
    for (const auto& [key, own_block] : own.blocks()) {
      OccupancyCellBlocks::Block& w = world.block(key);
      for (int i = 0; i < kBlockVoxels; ++i) {
        if (std::isnan(own_block[i])) continue;
        w[i] = std::isnan(w[i]) ? own_block[i] : std::clamp(w[i] + own_block[i], params.clamp_min, params.clamp_max);
      }
    }
  }
  return cells_in_key_order(world.blocks());
}

}  // namespace slamvdb
