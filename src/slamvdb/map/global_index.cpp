#include "slamvdb/map/global_index.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

GlobalIndex::GlobalIndex(double cell_size, int dim, bool single_view)
    : cell_size_(cell_size), inv_cell_size_(1.0 / cell_size), dim_(dim), single_view_(single_view) {
  if (!(cell_size > 0) || !std::isfinite(cell_size)) throw Error(fmt::format("index cell size {} must be > 0", cell_size));
}

IndexCellKey GlobalIndex::cell_of_entry(const Binding& b, SemanticLayer::Handle h) const {
  const Vec3d p_submap = center_of_key(b.layer->key_of(h), b.voxel_size);
  return cell_of(b.T_world_submap * p_submap);
}

void GlobalIndex::insert(const IndexCellKey& cell, EntryRef ref) {
  const auto [it, inserted] = cell_slot_.try_emplace(cell, static_cast<uint32_t>(cells_.size()));
  if (inserted) cells_.push_back({cell, {}});
  // Kept in (submap, voxel key) order, so that a cell's mean is summed in the same order whatever
  // the history of the index (a loaded map reads bit for bit like the map that was saved).
  auto& refs = cells_[it->second].refs;
  const auto less = [&](const EntryRef& a, const EntryRef& b) {
    if (a.submap != b.submap) return a.submap < b.submap;
    return bindings_[a.submap].layer->key_of(a.handle) < bindings_[b.submap].layer->key_of(b.handle);
  };
  refs.insert(std::upper_bound(refs.begin(), refs.end(), ref, less), ref);
  ++num_refs_;
}

void GlobalIndex::erase(const IndexCellKey& cell, EntryRef ref) {
  const auto it = cell_slot_.find(cell);
  if (it == cell_slot_.end()) return;
  const uint32_t slot = it->second;
  auto& refs = cells_[slot].refs;
  const auto r = std::find_if(refs.begin(), refs.end(),
                              [&](const EntryRef& e) { return e.submap == ref.submap && e.handle == ref.handle; });
  if (r == refs.end()) return;
  refs.erase(r);
  --num_refs_;
  if (!refs.empty()) return;
  // Swap-remove the empty cell so that cells_ stays dense.
  cell_slot_.erase(it);
  if (slot + 1 != cells_.size()) {
    cells_[slot] = std::move(cells_.back());
    cell_slot_[cells_[slot].key] = slot;
  }
  cells_.pop_back();
}

void GlobalIndex::bin_all(uint32_t slot) {
  Binding& b = bindings_[slot];
  b.centres_submap.setEmpty();
  b.layer->for_each([&](SemanticLayer::Handle h) {
    b.centres_submap.extend(center_of_key(b.layer->key_of(h), b.voxel_size));
    insert(cell_of_entry(b, h), {slot, h});
  });
}

void GlobalIndex::unbin_all(uint32_t slot) {
  const Binding& b = bindings_[slot];
  b.layer->for_each([&](SemanticLayer::Handle h) { erase(cell_of_entry(b, h), {slot, h}); });
}

void GlobalIndex::add_submap(uint32_t slot, const SemanticLayer& layer, double voxel_size, const Pose& T_world_submap) {
  if (layer.dim() != dim_)
    throw Error(fmt::format("a submap with {}-d embeddings cannot join a {}-d index", layer.dim(), dim_));
  if (slot >= bindings_.size()) bindings_.resize(slot + 1);
  if (bindings_[slot].layer) throw Error(fmt::format("submap slot {} is already in the index", slot));
  bindings_[slot] = {&layer, voxel_size, T_world_submap, {}};  // bin_all sets the bounds
  cell_slot_.reserve(cell_slot_.size() + layer.size());
  bin_all(slot);
}

void GlobalIndex::remove_submap(uint32_t slot) {
  if (slot >= bindings_.size() || !bindings_[slot].layer) return;
  unbin_all(slot);
  bindings_[slot] = {};
}

void GlobalIndex::move_submap(uint32_t slot, const Pose& T_world_submap) {
  if (slot >= bindings_.size() || !bindings_[slot].layer) throw Error(fmt::format("submap slot {} is not in the index", slot));
  unbin_all(slot);
  bindings_[slot].T_world_submap = T_world_submap;
  bin_all(slot);
}

void GlobalIndex::apply_changes(uint32_t slot, const SemanticLayer::Changes& changes) {
  if (slot >= bindings_.size() || !bindings_[slot].layer) return;
  Binding& b = bindings_[slot];
  // Erased first: an entry added and erased within one log is then skipped below (count 0).
  for (const auto& [h, key] : changes.erased)
    erase(cell_of(b.T_world_submap * center_of_key(key, b.voxel_size)), {slot, h});
  for (const SemanticLayer::Handle h : changes.added)
    if (b.layer->count_of(h) > 0) {
      b.centres_submap.extend(center_of_key(b.layer->key_of(h), b.voxel_size));
      insert(cell_of_entry(b, h), {slot, h});
    }
}

std::size_t GlobalIndex::best_ref(const Cell& c) const {
  std::size_t best = 0;
  for (std::size_t k = 1; k < c.refs.size(); ++k)
    if (bindings_[c.refs[k].submap].layer->weight_of(c.refs[k].handle) >
        bindings_[c.refs[best].submap].layer->weight_of(c.refs[best].handle))
      best = k;
  return best;
}

IndexedVoxel GlobalIndex::read(std::size_t i, float* scratch) const {
  const Cell& c = cells_[i];
  IndexedVoxel v;
  v.cell = c.key;
  v.position_world = center_of_key(c.key, cell_size_);
  v.entries = static_cast<uint32_t>(c.refs.size());
  if (c.refs.size() == 1 || single_view_) {
    // Count, weight, statistics and embedding all of the one entry read (single_view: the other
    // entries' views were discarded, so their counts would overstate the observations behind it).
    const EntryRef& r = c.refs[c.refs.size() == 1 ? 0 : best_ref(c)];
    const SemanticLayer& layer = *bindings_[r.submap].layer;
    v.count = layer.count_of(r.handle);
    v.weight = layer.weight_of(r.handle);
    v.embedding = layer.embedding_of(r.handle);
    return v;
  }
  // Several submaps saw this place: the weighted mean (paper 6.2.3: count-weighted), summed count.
  uint64_t total = 0;
  double weight = 0;
  for (const EntryRef& r : c.refs) {
    total += bindings_[r.submap].layer->count_of(r.handle);
    weight += bindings_[r.submap].layer->weight_of(r.handle);
  }
  const auto dim = static_cast<std::size_t>(dim_);
  std::fill_n(scratch, dim, 0.0f);
  for (const EntryRef& r : c.refs) {
    const SemanticLayer& layer = *bindings_[r.submap].layer;
    const float w = static_cast<float>(static_cast<double>(layer.weight_of(r.handle)) / weight);
    kernels::add_scaled(scratch, layer.embedding_of(r.handle), w, dim);
  }
  v.count = static_cast<uint32_t>(std::min<uint64_t>(total, UINT32_MAX));
  v.weight = static_cast<float>(weight);
  v.embedding = {scratch, EmbeddingPrecision::kFloat32};
  return v;
}

VoxelStatistics GlobalIndex::statistics(std::size_t i, const float* mean) const {
  const Cell& c = cells_[i];
  if (c.refs.size() == 1 || single_view_) {
    const EntryRef& r = c.refs[c.refs.size() == 1 ? 0 : best_ref(c)];
    return bindings_[r.submap].layer->statistics_of(r.handle);
  }
  // Chan et al.: sum_k S_k + sum_k W_k |m_k - m|^2 about the combined mean m.
  VoxelStatistics s{0.f, 0.f};
  const auto dim = static_cast<std::size_t>(dim_);
  for (const EntryRef& r : c.refs) {
    const SemanticLayer& layer = *bindings_[r.submap].layer;
    const VoxelStatistics e = layer.statistics_of(r.handle);
    s.weight += e.weight;
    s.spread += e.spread + e.weight * kernels::squared_distance(layer.embedding_of(r.handle), mean, dim);
  }
  return s;
}

GlobalIndex::Parts GlobalIndex::parts(std::size_t i, float* scratch) const {
  const Cell& c = cells_[i];
  Parts p;
  if (c.refs.size() > 2 && !single_view_) {
    const IndexedVoxel v = read(i, scratch);
    p.embedding.view[0] = v.embedding, p.count = v.count;
    p.stats = statistics(i, scratch);
    return p;
  }
  if (c.refs.size() == 1 || single_view_) {  // one entry, as read() reads it
    const EntryRef& r = c.refs[c.refs.size() == 1 ? 0 : best_ref(c)];
    const SemanticLayer& layer = *bindings_[r.submap].layer;
    p.count = layer.count_of(r.handle);
    p.embedding.view[0] = layer.embedding_of(r.handle);
    p.stats = layer.statistics_of(r.handle);
    return p;
  }
  uint64_t total = 0;
  double weight = 0;
  for (std::size_t k = 0; k < c.refs.size(); ++k) {
    const SemanticLayer& layer = *bindings_[c.refs[k].submap].layer;
    total += layer.count_of(c.refs[k].handle);
    weight += layer.weight_of(c.refs[k].handle);
  }
  p.count = static_cast<uint32_t>(std::min<uint64_t>(total, UINT32_MAX));
  p.embedding.n = 2;
  VoxelStatistics s[2];
  for (std::size_t k = 0; k < 2; ++k) {
    const SemanticLayer& layer = *bindings_[c.refs[k].submap].layer;
    p.embedding.view[k] = layer.embedding_of(c.refs[k].handle);
    p.embedding.weight[k] = static_cast<float>(static_cast<double>(layer.weight_of(c.refs[k].handle)) / weight);
    s[k] = layer.statistics_of(c.refs[k].handle);
  }
  // Chan's pairwise rule: the same value as statistics() about the combined mean, without writing it.
  p.stats = combine_statistics(s[0], s[1],
                               kernels::squared_distance(p.embedding.view[0], p.embedding.view[1], static_cast<std::size_t>(dim_)));
  return p;
}

std::optional<IndexedVoxel> GlobalIndex::read_at(const Vec3d& p_world, float* scratch) const {
  if (!in_grid_extent(p_world * inv_cell_size_)) return std::nullopt;
  const auto it = cell_slot_.find(cell_of(p_world));
  if (it == cell_slot_.end()) return std::nullopt;
  return read(it->second, scratch);
}

std::optional<std::size_t> GlobalIndex::find(const IndexCellKey& cell) const {
  const auto it = cell_slot_.find(cell);
  if (it == cell_slot_.end()) return std::nullopt;
  return it->second;
}

std::vector<std::size_t> GlobalIndex::order_by_key() const {
  std::vector<std::size_t> order(cells_.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return cells_[a].key < cells_[b].key; });
  return order;
}

std::size_t GlobalIndex::memory_bytes() const {
  std::size_t n = cells_.capacity() * sizeof(Cell) + cell_slot_.capacity() * (sizeof(std::pair<IndexCellKey, uint32_t>) + 1) +
                  bindings_.capacity() * sizeof(Binding);
  for (const Cell& c : cells_)
    if (c.refs.size() > 1) n += c.refs.capacity() * sizeof(EntryRef);
  return n;
}

}  // namespace slamvdb
