#pragma once
// Marking the voxels that clearing rays cross: the hot loop of occupancy integration (about 5
// million voxel visits per 131k-point scan at 25 m clearing). Hand-written because a general DDA
// (traverse_voxels) costs ~2.5 ns per visit, mostly in mispredicted branches choosing the axis to
// step, and OctoMap's cost is what this is measured against. Here the DDA runs on integers:
// crossing parameters in fixed point and voxel coordinates kept "dilated" in their bit positions of
// the bitmap index, so that a step is a handful of branch-free integer operations, eight rays at a
// time with AVX2 (scalar fallback: same arithmetic, same result, one ray at a time).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/keys.hpp"

namespace slamvdb {

// A cube of 2^side_bits blocks per side, block-aligned, with one 8^3 brick of bits per block (8
// words: one per z, bit (y & 7) * 8 + (x & 7)), bricks in (z, y, x) order. Voxel (x, y, z)
// relative to `lo` has bit index (x & 7) | (y & 7) << 3 | (z & 7) << 6 | brick << 9 with brick =
// (x >> 3) | (y >> 3) << b | (z >> 3) << 2b: each coordinate owns a fixed set of index bits.
struct RayCube {
  VoxelKey lo;        // first voxel, a block corner
  int side_bits = 0;  // 1..6 (6: 512 voxels, a 16 MB bitmap)

  // The smallest cube around `center` holding every voxel within `reach` voxels of it (nullopt-like
  // side_bits 0 when more than 2^6 blocks per side would be needed).
  static RayCube around(const VoxelKey& center, int reach);
  int side_voxels() const { return kBlockSide << side_bits; }
  std::size_t num_bricks() const { return std::size_t{1} << (3 * side_bits); }
  // Words of a bitmap: the bricks and one more that finished lanes write to (see the .cpp).
  std::size_t num_words() const { return (num_bricks() + 1) * 8; }
  BlockKey block_of_brick(std::size_t brick) const {
    const std::size_t m = (std::size_t{1} << side_bits) - 1;
    return BlockKey((lo.x() >> kBlockBits) + static_cast<int>(brick & m),
                    (lo.y() >> kBlockBits) + static_cast<int>((brick >> side_bits) & m),
                    (lo.z() >> kBlockBits) + static_cast<int>(brick >> (2 * side_bits)));
  }
  bool contains(const VoxelKey& k) const {
    const auto n = static_cast<unsigned>(side_voxels());
    return static_cast<unsigned>(k.x() - lo.x()) < n && static_cast<unsigned>(k.y() - lo.y()) < n &&
           static_cast<unsigned>(k.z() - lo.z()) < n;
  }
  // Bit index of a voxel inside the cube.
  uint32_t bit_of(const VoxelKey& k) const {
    const auto dilate = [this](int c, int axis) {
      const auto u = static_cast<uint32_t>(c);
      return ((u & 7u) << (3 * axis)) | ((u >> 3) << (9 + axis * side_bits));
    };
    return dilate(k.x() - lo.x(), 0) | dilate(k.y() - lo.y(), 1) | dilate(k.z() - lo.z(), 2);
  }
};

// Sets, in `words` (cube.num_words(), not shared with another thread while this runs), the bit of
// every voxel that the segment from `from` to rays[i], for each i in `to`, crosses, excluding the
// voxel of its end: the voxels traverse_voxels(from, rays[i]) visits, except where a segment passes
// within about 1e-5 of a voxel's edge (the crossing parameters are fixed point). `from` and the
// rays are in cell units and every segment lies inside the cube. The result does not depend on
// the CPU.
void mark_segments(const RayCube& cube, const Vec3d& from, const Vec3d* rays, std::span<const uint32_t> to,
                   uint64_t* words);

// The same without AVX2 (tests compare the two).
void mark_segments_scalar(const RayCube& cube, const Vec3d& from, const Vec3d* rays, std::span<const uint32_t> to,
                          uint64_t* words);

// The order integrate_scan casts rays in. Rays are grouped by direction: the cells of a cube map
// around the sensor, kRayTiles x kRayTiles per face (about 5.6 degrees at 16).
constexpr int kRayTiles = 16;
constexpr uint32_t kNumRayTiles = 6 * kRayTiles * kRayTiles;

// The tile of a ray's direction d (not necessarily unit length). In float: it only orders rays.
inline uint32_t ray_tile_of(const Vec3f& d) {
  const float ax = std::abs(d.x()), ay = std::abs(d.y()), az = std::abs(d.z());
  const int face = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
  const float m = 1.0f / std::max({ax, ay, az}), u = d[(face + 1) % 3] * m, v = d[(face + 2) % 3] * m;
  const int iu = std::min(kRayTiles - 1, static_cast<int>((u + 1) * (kRayTiles / 2))),
            iv = std::min(kRayTiles - 1, static_cast<int>((v + 1) * (kRayTiles / 2)));
  return static_cast<uint32_t>(((2 * face + (d[face] < 0)) * kRayTiles + iu) * kRayTiles + iv);
}

// A cast ray's sort key is its tile, then its length in voxels (10 bits, saturated); dropped rays
// get kNotCast.
constexpr uint32_t kNotCast = ~0u;

// The indices of the rays to cast (sort keys other than kNotCast), in casting order (see the .cpp).
std::vector<uint32_t> casting_order(const std::vector<uint32_t>& sort_keys);

// Bitmaps for integrate_scan, handed back clear: allocating and zeroing 4 MB per thread per scan
// cost more than the update pass, which clears what it reads. Shared by every grid (a pool per grid
// would multiply with the submaps); a scan takes one per thread that joins it. A bitmap not marked
// clear (a scan that threw) is dropped instead of handed back.
class PooledBitmap {
 public:
  explicit PooledBitmap(std::size_t words);  // all zero
  PooledBitmap(PooledBitmap&&) = default;
  PooledBitmap& operator=(PooledBitmap&&) = delete;
  ~PooledBitmap();
  uint64_t* data() { return words_.data(); }
  void set_clear() { clear_ = true; }  // every bit is 0 again

 private:
  std::vector<uint64_t> words_;
  bool clear_ = false;
};

}  // namespace slamvdb
