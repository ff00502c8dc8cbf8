// The index's answers about regions of the world: which submaps can hold cells in a box (their
// world bounds, anchor * local bounds), and which cells lie in it, reading only those submaps.
#include <algorithm>

#include "slamvdb/map/global_index.hpp"

namespace slamvdb {

Eigen::AlignedBox3d GlobalIndex::submap_bounds_world(uint32_t slot) const {
  Eigen::AlignedBox3d world;  // empty
  if (slot >= bindings_.size() || !bindings_[slot].layer || bindings_[slot].centres_submap.isEmpty()) return world;
  const Binding& b = bindings_[slot];
  // The box's eight corners at the anchor: a rotated box is held by the box of its corners.
  for (int corner = 0; corner < 8; ++corner)
    world.extend(b.T_world_submap * b.centres_submap.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)));
  // A cell's centre lies within half a cell of the entries binned in it: a whole cell is margin
  // enough for the rounding of the transform as well.
  world.min().array() -= cell_size_;
  world.max().array() += cell_size_;
  return world;
}

std::vector<std::size_t> GlobalIndex::cells_in_box(const Eigen::AlignedBox3d& box_world, std::size_t* submaps_read) const {
  std::vector<std::size_t> out;
  if (submaps_read) *submaps_read = 0;
  if (box_world.isEmpty() || cells_.empty()) return out;
  const auto centre_inside = [&](const IndexCellKey& cell) { return box_world.contains(center_of_key(cell, cell_size_)); };
  std::vector<uint32_t> slots;
  std::size_t entries = 0;
  for (uint32_t slot = 0; slot < bindings_.size(); ++slot) {
    if (!bindings_[slot].layer || !submap_bounds_world(slot).intersects(box_world)) continue;
    slots.push_back(slot);
    entries += bindings_[slot].layer->size();
  }
  if (entries > cells_.size()) {
    // The submaps in the box hold more entries than the index has cells: a scan of the cells is cheaper.
    if (submaps_read) *submaps_read = slots.size();
    for (std::size_t i = 0; i < cells_.size(); ++i)
      if (centre_inside(cells_[i].key)) out.push_back(i);
    return out;
  }
  // An entry lies within half a cell of its cell's centre: entries farther than a cell from the
  // box are skipped before their cell is looked up.
  Eigen::AlignedBox3d near_box = box_world;
  near_box.min().array() -= cell_size_;
  near_box.max().array() += cell_size_;
  for (const uint32_t slot : slots) {
    const Binding& b = bindings_[slot];
    b.layer->for_each([&](SemanticLayer::Handle h) {
      const Vec3d p_world = b.T_world_submap * center_of_key(b.layer->key_of(h), b.voxel_size);
      if (!near_box.contains(p_world)) return;
      const IndexCellKey cell = cell_of(p_world);  // as cell_of_entry bins it
      if (!centre_inside(cell)) return;
      if (const auto it = cell_slot_.find(cell); it != cell_slot_.end()) out.push_back(it->second);
    });
  }
  if (submaps_read) *submaps_read = slots.size();
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());  // a cell shared by several submaps once
  return out;
}

}  // namespace slamvdb
