// The index's region answers: cells_in_box gives exactly the cells whose centre is in the box (a
// brute-force filter of every cell agrees on random boxes, on both of its paths), reads only the
// submaps whose world bounds meet the box, and follows a submap that moves.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "slamvdb/map/global_index.hpp"

namespace slamvdb {
namespace {

constexpr double kPatchVoxel = 0.25;

// Four 3 x 3 x 0.5 m patches of 4-d entries, anchored apart (one rotated about z by 30 degrees,
// all off the cell grid), and a fifth over the first, so that submaps share cells and all of them
// hold more entries than the index has cells.
struct FourPatches {
  std::vector<std::unique_ptr<SemanticLayer>> layers;
  std::vector<Pose> anchors;
  GlobalIndex index{kPatchVoxel, 4};
  FourPatches() {
    const Vec3d origins[5] = {{0.1, 0.05, 0}, {10.1, 0.05, 0}, {0.1, 10.05, 0}, {5.07, 5.11, 0.3}, {0.2, 0.1, 0}};
    for (int s = 0; s < 5; ++s) {
      auto layer = std::make_unique<SemanticLayer>(SemanticParams{4, EmbeddingPrecision::kFloat32});
      for (int x = 0; x < 12; ++x)
        for (int y = 0; y < 12; ++y)
          for (int z = 0; z < 2; ++z) {
            const float e[4] = {1.f + static_cast<float>(x), static_cast<float>(y), static_cast<float>(s), 1.f};
            layer->set({x, y, z}, e, 1);
          }
      Pose T = Pose::Identity();
      if (s == 3) T.linear() = Eigen::AngleAxisd(M_PI / 6, Vec3d::UnitZ()).toRotationMatrix();
      T.translation() = origins[s];
      index.add_submap(static_cast<uint32_t>(s), *layer, kPatchVoxel, T);
      layers.push_back(std::move(layer));
      anchors.push_back(T);
    }
  }
  std::vector<std::size_t> brute_force(const Eigen::AlignedBox3d& box) const {
    std::vector<std::size_t> out;
    for (std::size_t i = 0; i < index.size(); ++i)
      if (box.contains(center_of_key(index.key(i), index.cell_size()))) out.push_back(i);
    return out;
  }
};

Eigen::AlignedBox3d box_of(double x0, double y0, double z0, double x1, double y1, double z1) {
  return Eigen::AlignedBox3d(Vec3d(x0, y0, z0), Vec3d(x1, y1, z1));
}

TEST(GlobalIndexRegion, CellsInABoxAreExactlyTheCellsWhoseCentreIsInIt) {
  const FourPatches f;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coord(-2.0, 14.0), side(0.1, 6.0), height(-0.5, 1.0);
  std::size_t non_empty = 0;
  for (int k = 0; k < 60; ++k) {
    const double x = coord(rng), y = coord(rng), z = height(rng);
    const auto box = box_of(x, y, z, x + side(rng), y + side(rng), z + side(rng) / 4);
    const auto expected = f.brute_force(box);
    non_empty += !expected.empty();
    EXPECT_EQ(f.index.cells_in_box(box), expected) << box.min().transpose() << " .. " << box.max().transpose();
  }
  EXPECT_GT(non_empty, 10u);  // the boxes did meet the patches
  // A box over everything takes the scan path (the submaps hold more entries than there are cells).
  std::size_t read = 0;
  const auto everything = box_of(-100, -100, -100, 100, 100, 100);
  EXPECT_EQ(f.index.cells_in_box(everything, &read), f.brute_force(everything));
  EXPECT_EQ(f.index.cells_in_box(everything).size(), f.index.size());
  EXPECT_EQ(read, 5u);
}

TEST(GlobalIndexRegion, OnlySubmapsWhoseWorldBoundsMeetTheBoxAreRead) {
  FourPatches f;
  // Each submap's world bounds hold the centres of all its cells.
  for (uint32_t s = 0; s < 5; ++s) {
    const Eigen::AlignedBox3d bounds = f.index.submap_bounds_world(s);
    ASSERT_FALSE(bounds.isEmpty());
    f.layers[s]->for_each([&](SemanticLayer::Handle h) {
      const Vec3d p = f.anchors[s] * center_of_key(f.layers[s]->key_of(h), kPatchVoxel);
      EXPECT_TRUE(bounds.contains(center_of_key(f.index.cell_of(p), kPatchVoxel)));
    });
  }
  EXPECT_TRUE(f.index.submap_bounds_world(9).isEmpty());
  std::size_t read = 99;
  const auto in_second = box_of(11, 1, -1, 12, 2, 1);  // inside submap 1 only
  const auto cells = f.index.cells_in_box(in_second, &read);
  EXPECT_EQ(read, 1u);
  EXPECT_EQ(cells, f.brute_force(in_second));
  EXPECT_FALSE(cells.empty());
  const auto nowhere = box_of(40, 40, 0, 41, 41, 1);
  EXPECT_TRUE(f.index.cells_in_box(nowhere, &read).empty());
  EXPECT_EQ(read, 0u);
  // A moved submap is found where it went, and no longer where it was.
  Pose T = Pose::Identity();
  T.translation() = Vec3d(40.02, 40.03, 0);
  f.index.move_submap(1, T);
  EXPECT_EQ(f.index.cells_in_box(nowhere, &read), f.brute_force(nowhere));
  EXPECT_EQ(read, 1u);
  EXPECT_FALSE(f.brute_force(nowhere).empty());
  EXPECT_TRUE(f.index.cells_in_box(in_second, &read).empty());
  EXPECT_EQ(read, 0u);
}

}  // namespace
}  // namespace slamvdb
