// The embedding cap's bound (fleet/fleet_summary.hpp), without a database: no vector of a layer,
// and no non-negative mix of vectors of several caps' layers (an index cell shared by submaps),
// scores a cosine above the bound of the cap that encloses them; a cap of 90 degrees bounds nothing.
#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "slamvdb/fleet/fleet_summary.hpp"

namespace slamvdb::fleet {
namespace {

SemanticLayer summary_test_layer(int axis, float tilt, unsigned seed, std::vector<Eigen::VectorXf>* kept) {
  SemanticParams params;
  params.dim = 8;
  params.precision = EmbeddingPrecision::kFloat32;
  SemanticLayer layer(params);
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> noise(-tilt, tilt);
  for (int i = 0; i < 200; ++i) {
    Eigen::VectorXf e(8);
    for (int d = 0; d < 8; ++d) e[d] = noise(random);
    e[axis] = 1.0f;
    layer.set({i, 0, 0}, e.data(), 1);
    kept->push_back(e);
  }
  const float zero[8] = {};
  layer.set({-1, 0, 0}, zero, 1);  // scores nothing: left out of the cap
  return layer;
}

TEST(FleetSummary, NoVectorNorAnyMixOfThemScoresAboveTheEnclosingCapsBound) {
  std::vector<Eigen::VectorXf> a, b;
  const auto cap_a = embedding_cap(summary_test_layer(0, 0.2f, 1, &a));
  const auto cap_b = embedding_cap(summary_test_layer(1, 0.2f, 2, &b));
  ASSERT_TRUE(cap_a && cap_b);
  EXPECT_GT(cap_a->radius, 0.1);
  EXPECT_LT(cap_a->radius, 0.6);
  const auto both = enclosing_cap(std::vector<EmbeddingCap>{*cap_a, *cap_b});
  ASSERT_TRUE(both);
  std::mt19937 random(3);
  std::uniform_real_distribution<float> uniform(-1.0f, 1.0f), weight(0.0f, 1.0f);
  double tightest = 1;
  for (int trial = 0; trial < 2000; ++trial) {
    Eigen::VectorXf q(8);
    for (int d = 0; d < 8; ++d) q[d] = uniform(random);
    q.normalize();
    const double bound_a = cap_cosine_bound(*cap_a, q), bound_both = cap_cosine_bound(*both, q);
    const Eigen::VectorXf& x = a[static_cast<std::size_t>(trial) % a.size()];
    const Eigen::VectorXf& y = b[static_cast<std::size_t>(trial * 7) % b.size()];
    const Eigen::VectorXf mix = weight(random) * x + weight(random) * y;
    EXPECT_LE(q.dot(x) / x.norm(), bound_a);
    EXPECT_LE(q.dot(mix) / mix.norm(), bound_both);
    tightest = std::min(tightest, bound_a - q.dot(x) / x.norm());
  }
  EXPECT_LT(tightest, 0.5);  // a bound, not a constant 1
  EXPECT_EQ(cap_cosine_bound(EmbeddingCap{{1, 0, 0, 0, 0, 0, 0, 0}, std::numbers::pi / 2}, Eigen::VectorXf::Unit(8, 1)), 1.0);
}

TEST(FleetSummary, ALayerWithoutUsableEmbeddingsHasNoCap) {
  SemanticParams params;
  params.dim = 4;
  SemanticLayer layer(params);
  EXPECT_FALSE(embedding_cap(layer));
  const float zero[4] = {};
  layer.set({0, 0, 0}, zero, 1);
  EXPECT_FALSE(embedding_cap(layer));
  EXPECT_FALSE(enclosing_cap({}));
}

}  // namespace
}  // namespace slamvdb::fleet
