#pragma once
// Integer grid coordinates. A voxel, an 8^3 block of voxels, a region of blocks and a cell of the
// global index are different things with the same shape; distinct types keep one from being
// passed where another is meant (conversions are explicit and named below).
#include <absl/hash/hash.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <limits>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

template <class Tag>
class GridKey : public Eigen::Vector3i {
 public:
  GridKey() : Eigen::Vector3i(0, 0, 0) {}
  GridKey(int x, int y, int z) : Eigen::Vector3i(x, y, z) {}
  // Explicit: an Eigen expression (or a key of another kind) becomes this kind only on purpose.
  template <class Derived>
  explicit GridKey(const Eigen::MatrixBase<Derived>& v) : Eigen::Vector3i(v) {}

  friend bool operator==(const GridKey& a, const GridKey& b) {
    return a.x() == b.x() && a.y() == b.y() && a.z() == b.z();
  }
  friend bool operator!=(const GridKey& a, const GridKey& b) { return !(a == b); }
  template <class OtherTag>
  bool operator==(const GridKey<OtherTag>&) const = delete;  // comparing different kinds is a bug
  template <class H>
  friend H AbslHashValue(H h, const GridKey& k) {
    return H::combine(std::move(h), k.x(), k.y(), k.z());
  }
  // Lexicographic in (z, y, x): the order files and exports are written in, so the same map always
  // gives the same bytes.
  friend bool operator<(const GridKey& a, const GridKey& b) {
    if (a.z() != b.z()) return a.z() < b.z();
    if (a.y() != b.y()) return a.y() < b.y();
    return a.x() < b.x();
  }
};

using VoxelKey = GridKey<struct VoxelKeyTag>;          // one voxel of a submap, in the submap frame
using BlockKey = GridKey<struct BlockKeyTag>;          // an 8^3 block of voxels (occupancy storage)
using RegionKey = GridKey<struct RegionKeyTag>;        // 8^3 blocks (neighbourhood queries)
using IndexCellKey = GridKey<struct IndexCellKeyTag>;  // one cell of the global index, world frame

inline constexpr int kBlockBits = 3;
inline constexpr int kBlockSide = 1 << kBlockBits;
inline constexpr int kBlockVoxels = kBlockSide * kBlockSide * kBlockSide;
inline constexpr int kRegionBits = 3;

inline BlockKey block_of(const VoxelKey& k) { return {k.x() >> kBlockBits, k.y() >> kBlockBits, k.z() >> kBlockBits}; }
inline int index_in_block(const VoxelKey& k) {
  constexpr int m = kBlockSide - 1;
  return (k.x() & m) | ((k.y() & m) << kBlockBits) | ((k.z() & m) << (2 * kBlockBits));
}
inline VoxelKey voxel_of(const BlockKey& b, int index) {
  constexpr int m = kBlockSide - 1;
  return {static_cast<int>(static_cast<uint32_t>(b.x()) << kBlockBits) | (index & m),
          static_cast<int>(static_cast<uint32_t>(b.y()) << kBlockBits) | ((index >> kBlockBits) & m),
          static_cast<int>(static_cast<uint32_t>(b.z()) << kBlockBits) | (index >> (2 * kBlockBits))};
}
inline RegionKey region_of(const BlockKey& b) {
  return {b.x() >> kRegionBits, b.y() >> kRegionBits, b.z() >> kRegionBits};
}

// The representable extent: voxel coordinates stay within +-2^30 so that every step of ray
// casting, block shifts and neighbour arithmetic stays inside int32 (at 0.25 m: +-268 000 km).
inline constexpr double kMaxGridCoordinate = 1 << 30;

// Whether a point given in grid units (metres / cell size) lies inside the representable extent.
inline bool in_grid_extent(const Vec3d& p_grid) {
  return std::abs(p_grid.x()) < kMaxGridCoordinate && std::abs(p_grid.y()) < kMaxGridCoordinate &&
         std::abs(p_grid.z()) < kMaxGridCoordinate;
}

// The key of the cell containing `p` (metres) on a grid of `inv_cell_size` cells per metre.
// The point must be inside the extent (in_grid_extent(p * inv_cell_size)).
// floor() of a value inside int's range, inline: without SSE4.1 (the baseline x86-64 build)
// std::floor is a library call, and keys are computed per point on hot paths. Same result.
inline int floor_to_int(double v) {
  const int i = static_cast<int>(v);  // towards zero
  return i - (v < i);
}
template <class Key>
Key key_of_point(const Vec3d& p, double inv_cell_size) {
  return Key(floor_to_int(p.x() * inv_cell_size), floor_to_int(p.y() * inv_cell_size),
             floor_to_int(p.z() * inv_cell_size));
}
template <class Key>
Vec3d center_of_key(const Key& k, double cell_size) {
  return (k.template cast<double>().array() + 0.5).matrix() * cell_size;
}

}  // namespace slamvdb
