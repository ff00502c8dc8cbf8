#include "slamvdb/map/semantic_layer.hpp"

#include <gtest/gtest.h>

#include <random>

#include "slamvdb/core/error.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {
namespace {

std::vector<float> random_unit(std::mt19937& rng, int dim) {
  std::normal_distribution<float> g;
  std::vector<float> v(dim);
  float n = 0;
  for (float& x : v) x = g(rng), n += x * x;
  for (float& x : v) x /= std::sqrt(n);
  return v;
}

TEST(SemanticLayer, RunningAverageIsTheExactMean) {
  for (const auto precision : {EmbeddingPrecision::kFloat32, EmbeddingPrecision::kFloat16}) {
    SemanticLayer layer({8, precision});
    std::mt19937 rng(1);
    std::vector<double> sum(8, 0.0);
    const int n = 50;
    for (int i = 0; i < n; ++i) {
      const auto x = random_unit(rng, 8);
      for (int c = 0; c < 8; ++c) sum[c] += x[c];
      layer.integrate({1, 2, 3}, x.data());
    }
    const auto slot = layer.find({1, 2, 3});
    ASSERT_TRUE(slot);
    EXPECT_EQ(layer.count_of(*slot), static_cast<uint32_t>(n));
    std::vector<float> v(8);
    layer.read(*slot, v.data());
    const double tol = precision == EmbeddingPrecision::kFloat32 ? 1e-6 : 2e-3;
    for (int c = 0; c < 8; ++c) EXPECT_NEAR(v[c], sum[c] / n, tol) << to_string(precision);
  }
}

TEST(SemanticLayer, Equation61StepByStep) {
  SemanticLayer layer({2, EmbeddingPrecision::kFloat32});
  const float a[2] = {1.0f, 0.0f}, b[2] = {0.0f, 1.0f}, c[2] = {0.0f, 4.0f};
  layer.integrate({0, 0, 0}, a);
  layer.integrate({0, 0, 0}, b);
  float v[2];
  layer.read(*layer.find({0, 0, 0}), v);
  EXPECT_FLOAT_EQ(v[0], 0.5f);
  EXPECT_FLOAT_EQ(v[1], 0.5f);
  layer.integrate({0, 0, 0}, c);  // (2 * (0.5, 0.5) + (0, 4)) / 3
  layer.read(*layer.find({0, 0, 0}), v);
  EXPECT_FLOAT_EQ(v[0], 1.0f / 3.0f);
  EXPECT_FLOAT_EQ(v[1], 5.0f / 3.0f);
}

// The measurement behind the fp16 default: after many fused views the fp16 mean stays within a
// small absolute error of the fp32 mean and keeps its direction (cosine) essentially exact.
TEST(SemanticLayer, Fp16ErrorBound) {
  const int dim = 512;
  SemanticLayer full({dim, EmbeddingPrecision::kFloat32}), half({dim, EmbeddingPrecision::kFloat16});
  std::mt19937 rng(5);
  const auto proto = random_unit(rng, dim);
  for (int i = 0; i < 2000; ++i) {
    auto x = random_unit(rng, dim);
    for (int c = 0; c < dim; ++c) x[c] = 0.8f * proto[c] + 0.6f * x[c];
    full.integrate({0, 0, 0}, x.data());
    half.integrate({0, 0, 0}, x.data());
  }
  std::vector<float> f(dim), h(dim);
  full.read(0, f.data());
  half.read(0, h.data());
  double dot = 0, nf = 0, nh = 0, max_err = 0;
  for (int c = 0; c < dim; ++c) {
    dot += f[c] * h[c], nf += f[c] * f[c], nh += h[c] * h[c];
    max_err = std::max(max_err, static_cast<double>(std::abs(f[c] - h[c])));
  }
  EXPECT_LT(max_err, 2e-3);
  EXPECT_GT(dot / std::sqrt(nf * nh), 1.0 - 1e-4);
}

TEST(SemanticLayer, MemoryPerEntryAt512dFp16IsUnder1100Bytes) {
  SemanticLayer layer({512, EmbeddingPrecision::kFloat16});
  std::vector<float> x(512, 0.01f);
  for (int i = 0; i < 100000; ++i) layer.integrate({i % 97, i / 97, i % 13}, x.data());
  EXPECT_LT(layer.bytes_per_entry(), 1100.0) << layer.bytes_per_entry();
  EXPECT_GT(layer.bytes_per_entry(), 1024.0);  // the payload itself: the measure is honest
}

TEST(SemanticLayer, EraseFreesTheSlotForReuse) {
  SemanticLayer layer({4});
  const float x[4] = {1, 2, 3, 4};
  layer.integrate({1, 1, 1}, x);
  layer.integrate({2, 2, 2}, x);
  EXPECT_TRUE(layer.erase({1, 1, 1}));
  EXPECT_FALSE(layer.erase({1, 1, 1}));
  EXPECT_FALSE(layer.find({1, 1, 1}));
  layer.integrate({3, 3, 3}, x);
  EXPECT_EQ(layer.size(), 2u);
  EXPECT_EQ(layer.count_of(*layer.find({3, 3, 3})), 1u);  // a reused slot starts from n = 0
}

TEST(SemanticLayer, RejectsBadParameters) {
  EXPECT_THROW(SemanticLayer({0}), Error);
  EXPECT_THROW(precision_from_string("fp8"), Error);
  EXPECT_EQ(precision_from_string("fp32"), EmbeddingPrecision::kFloat32);
  SemanticLayer layer({4});
  const float x[4] = {};
  EXPECT_THROW(layer.set({0, 0, 0}, x, 0), Error);
}

TEST(VoxelMap, AVoxelThatBecomesFreeLosesItsSemantics) {
  MapParams p;
  p.occupancy.voxel_size = 1.0;
  p.occupancy.min_point_range = 0.0;
  p.semantic.dim = 4;
  VoxelMap map(p);
  map.integrate_scan({Vec3f(5.5f, 0.5f, 0.5f)}, Pose::Identity());
  const float x[4] = {1, 0, 0, 0};
  map.semantics().integrate({5, 0, 0}, x);
  ASSERT_EQ(map.semantics().size(), 1u);
  for (int i = 0; i < 5; ++i) map.integrate_scan({Vec3f(9.5f, 0.5f, 0.5f)}, Pose::Identity());
  EXPECT_FALSE(map.occupancy().is_occupied({5, 0, 0}));
  EXPECT_EQ(map.semantics().size(), 0u);
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

TEST(SemanticLayer, HandlesAreStableAndLeadBackToTheirKeys) {
  SemanticLayer layer({4, EmbeddingPrecision::kFloat16});
  const float x[4] = {1, 2, 3, 4};
  std::vector<SemanticLayer::Handle> handles;
  for (int i = 0; i < 300; ++i) {  // more than two chunks
    layer.integrate({i, -i, 7}, x);
    handles.push_back(*layer.find({i, -i, 7}));
  }
  for (int i = 0; i < 300; i += 2) layer.erase({i, -i, 7});
  for (int i = 1; i < 300; i += 2) {
    EXPECT_EQ(*layer.find({i, -i, 7}), handles[i]);  // erasing others never moves an entry
    EXPECT_EQ(layer.key_of(handles[i]), VoxelKey(i, -i, 7));
  }
  std::size_t seen = 0, chunks = 0;
  layer.for_each_chunk([&](const SemanticLayer::ChunkView& v) {
    ++chunks;
    for (std::size_t s = 0; s < v.slots; ++s) {
      if (!v.counts[s]) continue;
      ++seen;
      EXPECT_EQ(v.keys[s], layer.key_of(v.first + s));
      EXPECT_EQ(v.embeddings + s * 4 * 2, layer.embedding_of(v.first + s).data);  // contiguous rows
    }
  });
  EXPECT_EQ(seen, 150u);
  EXPECT_EQ(chunks, 3u);
}

TEST(SemanticLayer, ChangeLogHoldsErasedSlotsUntilTaken) {
  SemanticLayer layer({2, EmbeddingPrecision::kFloat32});
  layer.set_change_tracking(true);
  const float x[2] = {1, 1};
  layer.integrate({1, 0, 0}, x);
  layer.integrate({2, 0, 0}, x);
  const auto h1 = *layer.find({1, 0, 0});
  layer.erase({1, 0, 0});
  layer.integrate({3, 0, 0}, x);  // must not reuse h1: a reader may still hold it
  EXPECT_NE(*layer.find({3, 0, 0}), h1);
  SemanticLayer::Changes c = layer.take_changes();
  EXPECT_EQ(c.added.size(), 3u);
  ASSERT_EQ(c.erased.size(), 1u);
  EXPECT_EQ(c.erased[0].first, h1);
  EXPECT_EQ(c.erased[0].second, VoxelKey(1, 0, 0));
  layer.integrate({4, 0, 0}, x);  // now the slot may be reused
  EXPECT_EQ(*layer.find({4, 0, 0}), h1);
  EXPECT_TRUE(layer.take_changes().erased.empty());
}

TEST(SemanticLayer, AccumulateIsTheCountWeightedMean) {
  for (const auto precision : {EmbeddingPrecision::kFloat32, EmbeddingPrecision::kFloat16}) {
    SemanticLayer layer({2, precision});
    const float a[2] = {1.0f, 0.0f}, b[2] = {0.0f, 1.0f};
    layer.set({0, 0, 0}, a, 3);
    layer.accumulate({0, 0, 0}, b, 1);  // (3 a + 1 b) / 4
    layer.accumulate({5, 0, 0}, b, 9);  // a new entry becomes the mean it is given
    float v[2];
    layer.read(*layer.find({0, 0, 0}), v);
    EXPECT_NEAR(v[0], 0.75f, 1e-3f);
    EXPECT_NEAR(v[1], 0.25f, 1e-3f);
    EXPECT_EQ(layer.count_of(*layer.find({0, 0, 0})), 4u);
    EXPECT_EQ(layer.count_of(*layer.find({5, 0, 0})), 9u);
    layer.set({1, 0, 0}, a, UINT32_MAX - 1);
    layer.accumulate({1, 0, 0}, b, 10);  // saturates instead of wrapping
    EXPECT_EQ(layer.count_of(*layer.find({1, 0, 0})), UINT32_MAX);
  }
}

// An entry written or merged without statistics does not claim to be perfectly consistent (spread
// 0, the most confident value): its spread is unknown, and stays unknown when combined; an entry
// fused from observations knows its spread.
TEST(SemanticLayer, EntriesWithoutStatisticsHaveAnUnknownSpread) {
  SemanticLayer layer({2, EmbeddingPrecision::kFloat32});
  const float a[2] = {1.0f, 0.0f}, b[2] = {0.0f, 1.0f};
  layer.set({0, 0, 0}, a, 3);
  layer.accumulate({1, 0, 0}, b, 4);
  layer.integrate({2, 0, 0}, a);
  layer.integrate({2, 0, 0}, b);
  for (const auto& [key, weight] : {std::pair{VoxelKey{0, 0, 0}, 3.f}, std::pair{VoxelKey{1, 0, 0}, 4.f}}) {
    EXPECT_FALSE(layer.statistics_of(*layer.find(key)).known());
    EXPECT_EQ(layer.statistics_of(*layer.find(key)).weight, weight);
  }
  EXPECT_TRUE(layer.statistics_of(*layer.find({2, 0, 0})).known());
  layer.accumulate({2, 0, 0}, b, 1);  // unknown wins in a combination
  EXPECT_FALSE(layer.statistics_of(*layer.find({2, 0, 0})).known());
  EXPECT_EQ(layer.statistics_of(*layer.find({2, 0, 0})).weight, 3.f);
}

TEST(SemanticLayer, ConvertingPrecisionKeepsHandlesAndValues) {
  SemanticLayer layer({8, EmbeddingPrecision::kFloat32});
  std::mt19937 rng(3);
  std::vector<std::vector<float>> values;
  for (int i = 0; i < 200; ++i) {
    values.push_back(random_unit(rng, 8));
    layer.set({i, 0, 0}, values.back().data(), 1 + i);
  }
  const auto h = *layer.find({17, 0, 0});
  layer.convert_to(EmbeddingPrecision::kFloat16);
  EXPECT_EQ(layer.precision(), EmbeddingPrecision::kFloat16);
  EXPECT_EQ(*layer.find({17, 0, 0}), h);
  float v[8];
  for (int i = 0; i < 200; ++i) {
    layer.read(*layer.find({i, 0, 0}), v);
    for (int c = 0; c < 8; ++c) EXPECT_NEAR(v[c], values[i][c], 1e-3f);
    EXPECT_EQ(layer.count_of(*layer.find({i, 0, 0})), static_cast<uint32_t>(1 + i));
  }
}

TEST(SemanticLayer, BulkInsertRefusesZeroCountsAndDuplicates) {
  SemanticLayer layer({2, EmbeddingPrecision::kFloat32});
  const std::vector<VoxelKey> keys = {{1, 2, 3}, {4, 5, 6}};
  const std::vector<uint32_t> counts = {2, 5};
  const float data[4] = {1, 2, 3, 4};
  layer.insert_raw(keys, counts, reinterpret_cast<const std::byte*>(data));
  float v[2];
  layer.read(*layer.find({4, 5, 6}), v);
  EXPECT_EQ(v[0], 3.0f);
  EXPECT_EQ(layer.count_of(*layer.find({4, 5, 6})), 5u);
  EXPECT_THROW(layer.insert_raw(keys, counts, reinterpret_cast<const std::byte*>(data)), Error);  // duplicates
  const std::vector<VoxelKey> fresh = {{9, 9, 9}};
  const std::vector<uint32_t> zero = {0};
  EXPECT_THROW(layer.insert_raw(fresh, zero, reinterpret_cast<const std::byte*>(data)), Error);
}

TEST(SemanticLayer, LastObservedSessionsAreTheSubmapsOwnUntilSetAndFollowARenumbering) {
  SemanticLayer layer({2, EmbeddingPrecision::kFloat32});
  const float e[2] = {1, 0};
  layer.integrate({0, 0, 0}, e);
  layer.integrate({1, 0, 0}, e);
  const auto a = *layer.find({0, 0, 0}), b = *layer.find({1, 0, 0});
  EXPECT_EQ(layer.stored_session_of(a), SemanticLayer::kOwnSession) << "fusion never names a session";
  EXPECT_FALSE(layer.has_other_sessions());
  layer.set_own_session(4);
  EXPECT_EQ(layer.session_of(a), 4);
  layer.set_session(b, 7);
  EXPECT_EQ(layer.session_of(b), 7);
  EXPECT_TRUE(layer.has_other_sessions());
  layer.set_session(b, 4);  // the own session is stored as such
  EXPECT_EQ(layer.stored_session_of(b), SemanticLayer::kOwnSession);
  EXPECT_THROW(layer.set_session(b, SemanticLayer::kOwnSession), Error);
  EXPECT_THROW(layer.set_session(b, -1), Error);
  layer.set_session(b, 7);
  EXPECT_THROW(layer.renumber_sessions({{4, 0}}), Error) << "session 7 is not listed";
  EXPECT_EQ(layer.session_of(b), 7) << "a refused renumbering changes nothing";
  layer.renumber_sessions({{4, 0}, {7, 1}});
  EXPECT_EQ(layer.session_of(a), 0);
  EXPECT_EQ(layer.session_of(b), 1);
  EXPECT_EQ(layer.own_session(), 0);
  // Bulk insert (map loading) takes the stored values as they are.
  SemanticLayer loaded({2, EmbeddingPrecision::kFloat32});
  const std::vector<VoxelKey> keys = {{1, 2, 3}, {4, 5, 6}};
  const std::vector<uint32_t> counts = {2, 5};
  const std::vector<uint16_t> sessions = {SemanticLayer::kOwnSession, 3};
  const float data[4] = {1, 2, 3, 4};
  loaded.insert_raw(keys, counts, reinterpret_cast<const std::byte*>(data), {}, sessions);
  loaded.set_own_session(2);
  EXPECT_EQ(loaded.session_of(*loaded.find({1, 2, 3})), 2);
  EXPECT_EQ(loaded.session_of(*loaded.find({4, 5, 6})), 3);
}

}  // namespace
}  // namespace slamvdb
