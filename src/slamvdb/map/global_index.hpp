#pragma once
// The global lookup index (paper section 6.2.3): a world-frame grid whose cells refer to the
// semantic entries of the submaps at their current world positions. Reading a cell gives the
// weighted mean of all entries in it (weighted by their observations' weight sums, which are their
// counts under the paper's rule: the paper's count-weighted mean) and their summed count; its
// statistics combine the entries' by Chan's rule (statistics()). Every retrieval reads the map
// through it, so a pose correction or a merge is visible to every reader at once without
// re-integrating any sensor data.
//
// The index holds references (submap slot, entry handle), not copies: an entry whose value a
// fusion step updates in place needs no index work; only entries that appear, disappear or move
// do. Moving one submap re-bins only that submap's entries.
#include <absl/container/flat_hash_map.h>
#include <absl/container/inlined_vector.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "slamvdb/map/semantic_layer.hpp"

namespace slamvdb {

// One cell of the index as a reader sees it.
struct IndexedVoxel {
  IndexCellKey cell;
  Vec3d position_world;     // the cell centre
  // Summed observation count and weight (= count under the paper's rule) of the entries in the
  // cell; under single_view those of the one entry read (the views behind its embedding).
  uint32_t count = 0;
  uint32_t entries = 0;     // how many submap entries the cell holds
  float weight = 0.f;
  EmbeddingView embedding;  // their weighted mean (a view of the submap's storage when one)
};

class GlobalIndex {
 public:
  struct EntryRef {
    uint32_t submap;  // the submap's slot (SemanticMap's table)
    SemanticLayer::Handle handle;
  };

  // single_view: a cell of several entries reads as its entry of the largest weight, not their mean
  // (SemanticParams::single_view): its embedding, count, weight and statistics all that entry's.
  explicit GlobalIndex(double cell_size, int dim, bool single_view = false);

  // Binds a submap's semantic layer (the layer must stay at its address while bound) and bins
  // all its entries at T_world_submap.
  void add_submap(uint32_t slot, const SemanticLayer& layer, double voxel_size, const Pose& T_world_submap);
  // Unbins every entry of the submap and forgets the layer.
  void remove_submap(uint32_t slot);
  // Re-bins only this submap's entries at the new pose.
  void move_submap(uint32_t slot, const Pose& T_world_submap);
  // Brings the index in step with a bound layer's change log (entries added or erased).
  void apply_changes(uint32_t slot, const SemanticLayer::Changes& changes);

  double cell_size() const { return cell_size_; }
  int dim() const { return dim_; }
  std::size_t size() const { return cells_.size(); }     // non-empty cells
  std::size_t num_refs() const { return num_refs_; }      // entries referenced
  IndexCellKey cell_of(const Vec3d& p_world) const { return key_of_point<IndexCellKey>(p_world, inv_cell_size_); }

  // Cell i (0 <= i < size()), resolved. `scratch` (dim floats) receives the mean of a cell with
  // several entries; the view points into it then. Cells are in no particular order.
  IndexedVoxel read(std::size_t i, float* scratch) const;
  // Cell i for readers that combine two entries themselves (in registers, without writing their
  // mean anywhere): its entries and their count weights when it has one or two, else its mean in
  // `scratch` as a single part. Most shared cells hold two entries (neighbouring submaps). Its
  // statistics as statistics() gives them (two entries: Chan's rule on their means' distance).
  struct Parts {
    CombinedView embedding;
    uint32_t count = 0;
    VoxelStatistics stats{};
  };
  Parts parts(std::size_t i, float* scratch) const;

  // The statistics of cell i's observations: weights summed, spreads combined with the squared
  // distances of the entries' means from `mean` (the cell's mean as read(), fp32; used only for a
  // cell of several entries).
  VoxelStatistics statistics(std::size_t i, const float* mean) const;

  // The cell at a world position, if it is not empty.
  std::optional<IndexedVoxel> read_at(const Vec3d& p_world, float* scratch) const;
  // Position of a cell in 0..size(), if it is not empty.
  std::optional<std::size_t> find(const IndexCellKey& cell) const;
  // 0..size() ordered by cell key: the order in which outputs are written, so that the same map
  // always gives the same bytes whatever the history of the index.
  std::vector<std::size_t> order_by_key() const;
  const IndexCellKey& key(std::size_t i) const { return cells_[i].key; }
  // The references of cell i (for tests and merges).
  std::span<const EntryRef> refs(std::size_t i) const { return {cells_[i].refs.data(), cells_[i].refs.size()}; }
  const SemanticLayer* layer(uint32_t slot) const { return slot < bindings_.size() ? bindings_[slot].layer : nullptr; }

  // The world box that holds the centre of every cell the submap's entries are binned in: its
  // entries' voxel centres at T_world_submap, grown by a cell. Only grows while the submap is
  // bound (an erased entry leaves it as large; a move or re-binning recomputes it), so it may be
  // larger than the submap but never smaller. Empty for a slot not bound or a layer without entries.
  Eigen::AlignedBox3d submap_bounds_world(uint32_t slot) const;
  // Positions (0..size(), ascending) of the cells whose centre lies in `box_world` (closed box).
  // Submaps whose world bounds miss the box are never read; the others are read entry by entry,
  // so the cost is what they hold, not the index's size (a scan of the cells instead when they
  // hold more entries than the index has cells). `submaps_read` receives how many were read.
  std::vector<std::size_t> cells_in_box(const Eigen::AlignedBox3d& box_world, std::size_t* submaps_read = nullptr) const;

  std::size_t memory_bytes() const;

 private:
  struct Cell {
    IndexCellKey key;
    absl::InlinedVector<EntryRef, 1> refs;
  };
  struct Binding {
    const SemanticLayer* layer = nullptr;
    double voxel_size = 0;
    Pose T_world_submap = Pose::Identity();  // the pose its entries are binned at
    Eigen::AlignedBox3d centres_submap;       // of its entries' voxel centres, submap frame (grows only)
  };
  IndexCellKey cell_of_entry(const Binding& b, SemanticLayer::Handle h) const;
  void insert(const IndexCellKey& cell, EntryRef ref);
  void erase(const IndexCellKey& cell, EntryRef ref);
  void bin_all(uint32_t slot);
  void unbin_all(uint32_t slot);

  double cell_size_, inv_cell_size_;
  int dim_;
  bool single_view_;
  // The entry of the largest weight among a cell's refs (single_view).
  std::size_t best_ref(const Cell& c) const;
  std::vector<Cell> cells_;                                  // dense: reads split it into ranges
  absl::flat_hash_map<IndexCellKey, uint32_t> cell_slot_;    // cell key -> position in cells_
  std::vector<Binding> bindings_;                            // by submap slot
  std::size_t num_refs_ = 0;
};

}  // namespace slamvdb
