#include "slamvdb/map/occupancy_raycast.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "slamvdb/map/occupancy_grid.hpp"

namespace slamvdb {
namespace {

int popcount(const std::vector<uint64_t>& words) {
  int n = 0;
  for (uint64_t w : words) n += __builtin_popcountll(w);
  return n;
}

std::vector<uint32_t> all_indices(std::size_t n) {
  std::vector<uint32_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<uint32_t>(i);
  return order;
}

// Segments from one origin to random ends within `reach` voxels, some of them from a voxel
// corner or along an axis (the ties of the DDA).
struct Fan {
  Vec3d from;
  std::vector<Vec3d> to;
  RayCube cube;
};
Fan make_fan(std::mt19937& rng, const Vec3d& from, int reach, int n) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Fan f{from, {}, RayCube::around(key_of_point<VoxelKey>(from, 1.0), reach)};
  for (int i = 0; i < n; ++i) {
    Vec3d d(u(rng), u(rng), 0.4 * u(rng));
    if (i % 17 == 0) d.y() = 0;                  // in a plane of the grid
    if (i % 29 == 0) d = Vec3d(u(rng), 0, 0);  // along an axis
    if (d.norm() == 0) d.x() = 1;
    f.to.push_back(from + d.normalized() * (reach - 1) * std::abs(u(rng)));
  }
  return f;
}

// The bitmap marks exactly traverse_voxels' voxels (the fixed-point crossings differ from the
// double ones only within ~1e-5 of a voxel edge, which random segments do not come near), with
// AVX2 and without, and only bits of the cube's voxels.
TEST(MarkSegments, MarksTheVoxelsTraverseVoxelsVisits) {
  std::mt19937 rng(11);
  const Vec3d origins[] = {{0.37, 0.61, 0.12}, {-1000.0, 37.0, 0.0}, {12345.5, -777.25, -3.0}, {8.0, 8.0, 8.0}};
  for (const Vec3d& from : origins) {
    const Fan f = make_fan(rng, from, 101, 3000);
    ASSERT_EQ(f.cube.side_bits, 5);
    std::vector<uint64_t> expected(f.cube.num_words()), scalar(f.cube.num_words()), fast(f.cube.num_words());
    for (const Vec3d& to : f.to)
      traverse_voxels(from, to, [&](const VoxelKey& k) {
        ASSERT_TRUE(f.cube.contains(k));
        const uint32_t bit = f.cube.bit_of(k);
        expected[bit >> 6] |= uint64_t{1} << (bit & 63);
      });
    const std::vector<uint32_t> all = all_indices(f.to.size());
    mark_segments_scalar(f.cube, from, f.to.data(), all, scalar.data());
    mark_segments(f.cube, from, f.to.data(), all, fast.data());
    // The last brick is where finished lanes write; it is not part of the cube.
    for (auto* v : {&scalar, &fast}) std::fill(v->end() - 8, v->end(), 0);
    EXPECT_GT(popcount(expected), 10000);
    EXPECT_EQ(scalar, expected) << "from " << from.transpose();
    EXPECT_EQ(fast, scalar) << "from " << from.transpose();
  }
}

// Any number of segments (not only multiples of the eight lanes), and none.
TEST(MarkSegments, AnyCount) {
  std::mt19937 rng(3);
  const Fan f = make_fan(rng, Vec3d(0.5, 0.5, 0.5), 20, 13);
  for (std::size_t n : {0, 1, 7, 8, 9, 13}) {
    std::vector<uint64_t> scalar(f.cube.num_words()), fast(f.cube.num_words());
    const std::vector<uint32_t> some = all_indices(n);
    mark_segments_scalar(f.cube, f.from, f.to.data(), some, scalar.data());
    mark_segments(f.cube, f.from, f.to.data(), some, fast.data());
    std::fill(fast.end() - 8, fast.end(), 0);
    EXPECT_EQ(fast, scalar) << n;
  }
}

TEST(RayCube, SizesAndBitIndices) {
  const RayCube c = RayCube::around(VoxelKey(-3, 5, 1000), 101);
  EXPECT_EQ(c.side_bits, 5);
  EXPECT_EQ(c.lo.x() % kBlockSide, 0);
  for (const VoxelKey& k : {VoxelKey(-104, 5, 1000), VoxelKey(98, -96, 899), VoxelKey(-3, 106, 1101)}) {
    ASSERT_TRUE(c.contains(k));
    const uint32_t bit = c.bit_of(k);
    EXPECT_EQ(c.block_of_brick(bit >> 9), block_of(k));
    EXPECT_EQ(static_cast<int>(bit & 511), index_in_block(k));
  }
  EXPECT_EQ(RayCube::around(VoxelKey(0, 0, 0), 3).side_bits, 1);
  EXPECT_EQ(RayCube::around(VoxelKey(0, 0, 0), 5000).side_bits, 0);  // too large
}

}  // namespace
}  // namespace slamvdb
