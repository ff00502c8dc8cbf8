// Questions limited to a region: a bad region is refused naming its part, and a search in a region
// answers exactly what the unrestricted search answers there (same cells, same order, top_k taken
// after the region), whether the region is a box, a ball, a vertical cylinder or a box and a ball.
#include "slamvdb/query/query_region.hpp"

#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "slamvdb/query/map_query.hpp"
#include "slamvdb/testing/error_of.hpp"

namespace slamvdb {
namespace {

using testing::error_of;

// The field a RegionError names for these parts ("" when accepted).
std::string region_refusal_field(std::optional<std::vector<double>> bbox, std::optional<std::vector<double>> near,
                          std::optional<double> radius) {
  try {
    make_region(bbox ? std::optional<std::span<const double>>(*bbox) : std::nullopt,
                near ? std::optional<std::span<const double>>(*near) : std::nullopt, radius);
  } catch (const RegionError& e) {
    EXPECT_FALSE(std::string(e.what()).empty());
    return e.field();
  }
  return "";
}

TEST(QueryRegion, ABadRegionIsRefusedNamingItsPart) {
  using V = std::vector<double>;
  EXPECT_EQ(region_refusal_field(V{0, 0, 0, 1, 1, 1}, {}, {}), "");
  EXPECT_EQ(region_refusal_field({}, V{1, 2}, 3.0), "");
  EXPECT_EQ(region_refusal_field(V{0, 0, 0, 1, 1, 1}, V{1, 2, 3}, 3.0), "");
  EXPECT_EQ(region_refusal_field(V{0, 0, 0, 1, 1}, {}, {}), "bbox");
  EXPECT_EQ(region_refusal_field(V{0, 0, 0, 1, 1, NAN}, {}, {}), "bbox");
  EXPECT_EQ(region_refusal_field(V{0, 2, 0, 1, 1, 1}, {}, {}), "bbox");  // ymin > ymax
  EXPECT_EQ(region_refusal_field({}, V{1}, 2.0), "near");
  EXPECT_EQ(region_refusal_field({}, V{1, 2, 3, 4}, 2.0), "near");
  EXPECT_EQ(region_refusal_field({}, V{1, 2}, {}), "radius");
  EXPECT_EQ(region_refusal_field({}, V{1, 2}, 0.0), "radius");
  EXPECT_EQ(region_refusal_field({}, V{1, 2}, -1.0), "radius");
  EXPECT_EQ(region_refusal_field({}, V{1, 2}, INFINITY), "radius");
  EXPECT_EQ(region_refusal_field({}, {}, 2.0), "near");
  EXPECT_EQ(region_refusal_field({}, {}, {}), "bbox");
  // The caller's names are the ones in the message.
  const std::vector<double> upside_down{0, 0, 5, 1, 1, 1};
  const std::string message = error_of([&] {
    make_region(std::span<const double>(upside_down), std::nullopt, std::nullopt, {"--bbox", "--near", "--radius"});
  });
  EXPECT_NE(message.find("--bbox: the z minimum 5 is above the maximum 1"), std::string::npos) << message;
}

TEST(QueryRegion, BallsCylindersAndBoxes) {
  const std::vector<double> centre3{1, 1, 0}, centre2{1, 1}, box{0, 0, -1, 10, 10, 1};
  const QueryRegion ball = make_region(std::nullopt, std::span<const double>(centre3), 2.0);
  const QueryRegion cylinder = make_region(std::nullopt, std::span<const double>(centre2), 2.0);
  const QueryRegion both = make_region(std::span<const double>(box), std::span<const double>(centre3), 2.0);
  EXPECT_TRUE(ball.contains({2.9, 1, 0}));
  EXPECT_FALSE(ball.contains({1, 1, 5}));
  EXPECT_TRUE(cylinder.contains({1, 1, 5}));  // any height
  EXPECT_FALSE(cylinder.contains({3.1, 1, 5}));
  EXPECT_FALSE(both.contains({-0.5, 1, 0}));  // in the ball, not in the box
  EXPECT_TRUE(both.contains({0.5, 1, 0}));
  EXPECT_TRUE(std::isinf(cylinder.bounds().max().z()));
  EXPECT_EQ(both.bounds().min(), Vec3d(0, 0, -1));
  EXPECT_EQ(both.bounds().max(), Vec3d(3, 3, 1));
}

// Three finished submaps of 4-d entries along x (0..6, 20..26 and a copy of the first shifted
// by half a voxel, so cells are shared), embeddings varying with position.
SemanticMap three_submaps() {
  MapParams p;
  p.occupancy.voxel_size = 0.5;
  p.semantic = {4, EmbeddingPrecision::kFloat32};
  p.submap_length = 0;
  SemanticMap map(p, {"test-space", "three", "hand-made test map"});
  const std::array<Vec3d, 3> anchors = {Vec3d(0, 0, 0), Vec3d(20, 0, 0), Vec3d(0.25, 0.1, 0)};
  for (int s = 0; s < 3; ++s) {
    VoxelMap v(p);
    for (int x = 0; x < 12; ++x)
      for (int y = 0; y < 12; ++y)
        for (int z = 0; z < 3; ++z) {
          const float e[4] = {1.f, 0.1f * static_cast<float>(x), 0.07f * static_cast<float>(y * (s + 1)),
                              0.05f * static_cast<float>(z)};
          v.semantics().set({x, y, z}, e, static_cast<uint32_t>(1 + x % 3));
        }
    SubmapInfo info;
    info.id = s;
    info.T_world_submap.translation() = anchors[static_cast<std::size_t>(s)];
    info.finished = true;
    map.add_finished_submap(info, std::move(v));
  }
  return map;
}

TEST(QueryRegion, ASearchInARegionIsTheUnrestrictedSearchThere) {
  const SemanticMap map = three_submaps();
  const float q[4] = {0.2f, 0.9f, 0.3f, 0.1f};
  const auto all = similarity_search(map, q);
  ASSERT_EQ(all.size(), map.num_index_cells());
  const std::vector<double> box{1.1, 1.3, -1, 4.2, 3.9, 0.7}, far_box{100, 100, 0, 110, 110, 5};
  const std::vector<double> near3{21.0, 2.0, 0.5}, near2{3.0, 3.0};
  const std::vector<QueryRegion> regions = {
      make_region(std::span<const double>(box), std::nullopt, std::nullopt),
      make_region(std::nullopt, std::span<const double>(near3), 1.7),
      make_region(std::nullopt, std::span<const double>(near2), 2.2),
      make_region(std::span<const double>(box), std::span<const double>(near2), 1.5),
      make_region(std::nullopt, std::span<const double>(near2), 500.0),  // the whole map
  };
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (const std::size_t top_k : {std::size_t{0}, std::size_t{7}}) {
      std::vector<IndexCellKey> expected;
      for (const ScoredCell& c : all)
        if (regions[r].contains(c.position_world) && (top_k == 0 || expected.size() < top_k)) expected.push_back(c.cell);
      ASSERT_FALSE(expected.empty()) << "region " << r;
      SearchOptions options;
      options.top_k = top_k;
      options.region = regions[r];
      std::vector<IndexCellKey> got;
      for (const ScoredCell& c : similarity_search(map, q, options)) got.push_back(c.cell);
      EXPECT_EQ(got, expected) << "region " << r << ", top_k " << top_k;
    }
  }
  // A region outside the map: no cells, not an error.
  SearchOptions outside;
  outside.region = make_region(std::span<const double>(far_box), std::nullopt, std::nullopt);
  EXPECT_TRUE(similarity_search(map, q, outside).empty());
}

}  // namespace
}  // namespace slamvdb
