// The global index's reads of a cell two submaps share: the count-weighted mean, and under the
// single-view baseline one entry whose count, weight and statistics go with its embedding.
#include "slamvdb/map/global_index.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "slamvdb/core/embedding_kernels.hpp"

namespace slamvdb {
namespace {

// Two single-view layers that each saw voxel `key` several times, with different best weights.
struct TwoSingleViewLayers {
  SemanticLayer a{{4, EmbeddingPrecision::kFloat32, true}}, b{{4, EmbeddingPrecision::kFloat32, true}};
  VoxelKey key{1, 2, 0};
  TwoSingleViewLayers() {
    const std::vector<float> xa{1, 0, 0, 0}, xb{0, 1, 0, 0};
    for (const float w : {0.5f, 0.9f, 0.7f}) a.keep_best(key, xa.data(), w);       // 3 views, best 0.9
    for (const float w : {0.2f, 0.6f, 0.3f, 0.4f, 0.5f}) b.keep_best(key, xb.data(), w);  // 5 views, best 0.6
  }
};

TEST(GlobalIndex, SingleViewReadsCountOnlyTheViewsOfTheEntryRead) {
  TwoSingleViewLayers layers;
  GlobalIndex index(1.0, 4, /*single_view=*/true);
  index.add_submap(0, layers.a, 0.25, Pose::Identity());
  index.add_submap(1, layers.b, 0.25, Pose::Identity());
  ASSERT_EQ(index.size(), 1u);
  std::vector<float> scratch(4), e(4);
  const IndexedVoxel v = index.read(0, scratch.data());
  EXPECT_EQ(v.entries, 2u);
  // The entry of the larger weight (submap 0's) is read: its embedding, and its 3 views, not the 8
  // of both submaps (submap 1's 5 views were discarded; counting them would raise n / (n + 2)).
  kernels::decode(v.embedding, e.data(), 4);
  EXPECT_EQ(e[0], 1.0f);
  EXPECT_EQ(v.count, 3u);
  EXPECT_FLOAT_EQ(v.weight, 0.9f);
  const GlobalIndex::Parts p = index.parts(0, scratch.data());
  EXPECT_EQ(p.count, 3u);
  EXPECT_FLOAT_EQ(p.stats.weight, 0.9f);
  EXPECT_FLOAT_EQ(index.statistics(0, scratch.data()).weight, 0.9f);
}

TEST(GlobalIndex, MeanReadsSumTheCountsAndWeightsOfEveryEntry) {
  TwoSingleViewLayers layers;
  GlobalIndex index(1.0, 4, /*single_view=*/false);
  index.add_submap(0, layers.a, 0.25, Pose::Identity());
  index.add_submap(1, layers.b, 0.25, Pose::Identity());
  std::vector<float> scratch(4);
  const IndexedVoxel v = index.read(0, scratch.data());
  EXPECT_EQ(v.count, 8u);
  EXPECT_FLOAT_EQ(v.weight, 1.5f);
  const GlobalIndex::Parts p = index.parts(0, scratch.data());
  EXPECT_EQ(p.count, 8u);
  EXPECT_FLOAT_EQ(p.stats.weight, 1.5f);
}

}  // namespace
}  // namespace slamvdb
