#include "slamvdb/query/query_classifier.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/testing/error_of.hpp"

namespace slamvdb {
namespace {

QuerySet random_queries(int n, int dim, uint32_t seed, std::vector<int> voids = {}) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  QuerySet q;
  q.model_id = "test";
  q.vectors.resize(n, dim);
  for (int k = 0; k < n; ++k) {
    q.names.push_back(fmt::format("c{}", k));  // not "c" + to_string: GCC 12 -Wrestrict false positive
    for (int d = 0; d < dim; ++d) q.vectors(k, d) = g(rng) * (1.f + k);  // queries need not be unit
  }
  q.void_classes = std::move(voids);
  return q;
}

std::vector<float> random_embeddings(std::size_t rows, int dim, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  std::uniform_real_distribution<float> scale(0.01f, 100.f);
  std::vector<float> x(rows * dim);
  for (std::size_t r = 0; r < rows; ++r) {
    const float s = scale(rng);  // embeddings need not be unit either
    for (int d = 0; d < dim; ++d) x[r * dim + d] = s * g(rng);
  }
  return x;
}

// Reference: cosines in double precision, the rule spelt out (best; void best -> second best).
QueryMatch reference(const float* x, const QuerySet& q, bool void_rule) {
  const int n = q.size(), dim = q.dim();
  double xn = 0;
  for (int d = 0; d < dim; ++d) xn += double(x[d]) * x[d];
  std::vector<double> cos(n);
  for (int k = 0; k < n; ++k) {
    double dot = 0, qn = 0;
    for (int d = 0; d < dim; ++d) dot += double(x[d]) * q.vectors(k, d), qn += double(q.vectors(k, d)) * q.vectors(k, d);
    cos[k] = dot / std::sqrt(xn * qn);
  }
  std::vector<int> order(n);
  for (int k = 0; k < n; ++k) order[k] = k;
  std::sort(order.begin(), order.end(), [&](int a, int b) { return cos[a] > cos[b]; });
  if (void_rule) std::erase_if(order, [&](int k) { return q.is_void(k); });
  QueryMatch m;
  m.class_index = order[0];
  m.score = static_cast<float>(cos[order[0]]);
  m.margin = order.size() > 1 ? static_cast<float>(cos[order[0]] - cos[order[1]]) : INFINITY;
  return m;
}

void expect_matches_reference(const QueryClassifier& c, const QuerySet& q, bool void_rule, std::size_t rows) {
  const auto x = random_embeddings(rows, q.dim(), 99);
  const auto out = c.classify(x);
  ASSERT_EQ(out.size(), rows);
  for (std::size_t r = 0; r < rows; ++r) {
    const QueryMatch ref = reference(x.data() + r * q.dim(), q, void_rule);
    if (out[r].class_index != ref.class_index) {
      EXPECT_LT(std::abs(ref.margin), 1e-5f) << "row " << r << ": only a near tie may flip";
      continue;
    }
    EXPECT_NEAR(out[r].score, ref.score, 2e-5f) << r;
    if (std::isinf(ref.margin)) EXPECT_TRUE(std::isinf(out[r].margin));
    else EXPECT_NEAR(out[r].margin, ref.margin, 2e-5f) << r;
  }
}

TEST(QueryClassifier, BothKernelsMatchAPerRowReference) {
  for (bool portable : {false, true}) {
    for (int n : {1, 2, 6, 7, 13, 20}) {
      for (int dim : {512, 67}) {  // 67: the AVX2 kernel's scalar tail
        SCOPED_TRACE(::testing::Message() << "portable " << portable << " n " << n << " dim " << dim);
        const QuerySet q = random_queries(n, dim, n * 31 + dim, n > 2 ? std::vector<int>{n - 1} : std::vector<int>{});
        expect_matches_reference(QueryClassifier(q, {.void_to_second_best = true, .portable_kernel = portable}), q,
                                 true, 3001);
        expect_matches_reference(QueryClassifier(q, {.void_to_second_best = false, .portable_kernel = portable}), q,
                                 false, 700);
      }
    }
  }
}

// The map's rows as the index hands them over: fp16 in place, singles and pairs of entries in any
// order. The AVX2 view kernels (one fp16 row, a pair combined in registers, fp32 rows) must give
// the portable kernel's answer on the same decoded values.
TEST(QueryClassifier, StoredRowKernelsMatchThePortableKernel) {
  for (int n : {1, 5, 6, 7}) {
    for (int dim : {512, 67}) {
      SCOPED_TRACE(::testing::Message() << "n " << n << " dim " << dim);
      const QuerySet q = random_queries(n, dim, n * 7 + dim, n > 2 ? std::vector<int>{n - 1} : std::vector<int>{});
      constexpr std::size_t kRows = 257;
      const auto x = random_embeddings(kRows * 2, dim, 5);
      std::vector<uint16_t> half(x.size());
      kernels::float_to_half(x.data(), half.data(), x.size());
      std::vector<float> decoded(x.size());
      kernels::half_to_float(half.data(), decoded.data(), x.size());
      std::mt19937 rng(n);
      std::vector<CombinedView> rows(kRows);
      std::vector<float> expected_rows(kRows * dim, 0.f);
      for (std::size_t r = 0; r < kRows; ++r) {
        CombinedView& v = rows[r];
        const int kind = static_cast<int>(rng() % 4);  // single fp16 (twice as often), pair, fp32
        v.view[0] = {half.data() + 2 * r * dim, EmbeddingPrecision::kFloat16};
        if (kind == 2) {
          v.n = 2, v.weight[0] = 0.25f, v.weight[1] = 0.75f;
          v.view[1] = {half.data() + (2 * r + 1) * dim, EmbeddingPrecision::kFloat16};
        } else if (kind == 3) {
          v.view[0] = {x.data() + 2 * r * dim, EmbeddingPrecision::kFloat32};
        }
        for (int d = 0; d < dim; ++d) {
          float& e = expected_rows[r * dim + d];
          if (kind == 3) e = x[2 * r * dim + d];
          else if (kind == 2) e = 0.25f * decoded[2 * r * dim + d] + 0.75f * decoded[(2 * r + 1) * dim + d];
          else e = decoded[2 * r * dim + d];
        }
      }
      const QueryClassifier fast(q), portable(q, {.portable_kernel = true});
      std::vector<QueryMatch> got(kRows);
      fast.classify_combined(rows.data(), kRows, got.data());
      const auto want = portable.classify(expected_rows);
      for (std::size_t r = 0; r < kRows; ++r) {
        if (got[r].class_index != want[r].class_index) {
          EXPECT_LT(std::abs(want[r].margin), 1e-5f) << "row " << r << ": only a near tie may flip";
          continue;
        }
        EXPECT_NEAR(got[r].score, want[r].score, 2e-5f) << r;
        if (!std::isinf(want[r].margin)) {
          EXPECT_NEAR(got[r].margin, want[r].margin, 2e-5f) << r;
        }
      }
    }
  }
}

TEST(QueryClassifier, VoidTakesTheSecondBestClass) {
  QuerySet q;
  q.model_id = "m";
  q.names = {"rough", "obstacle", "void"};
  q.vectors = QueryMatrix::Identity(3, 3);
  q.void_classes = {2};
  const std::vector<float> canopy = {0.2f, 0.5f, 0.9f};  // looks most like sky seen through leaves
  const QueryMatch ruled = classify_embeddings(canopy, q)[0];
  EXPECT_EQ(ruled.class_index, 1);
  const float norm = std::sqrt(0.04f + 0.25f + 0.81f);
  EXPECT_NEAR(ruled.score, 0.5f / norm, 1e-6f);
  EXPECT_NEAR(ruled.margin, 0.3f / norm, 1e-6f);  // to rough; void is out of the race
  const QueryMatch plain = QueryClassifier(q, {.void_to_second_best = false}).classify(canopy)[0];
  EXPECT_EQ(plain.class_index, 2);
  EXPECT_NEAR(plain.margin, 0.4f / norm, 1e-6f);

  q.void_classes = {1, 2};  // one class left: no runner-up
  const QueryMatch only = QueryClassifier(q).classify(canopy)[0];
  EXPECT_EQ(only.class_index, 0);
  EXPECT_TRUE(std::isinf(only.margin));
}

TEST(QueryClassifier, ZeroAndNonFiniteEmbeddingsHaveNoClassAndNoNaN) {
  for (bool portable : {false, true}) {
    const QuerySet q = random_queries(6, 16, 7, {5});
    const QueryClassifier c(q, {.portable_kernel = portable});
    std::vector<float> x = random_embeddings(5, 16, 8);
    std::fill(x.begin(), x.begin() + 16, 0.f);
    x[16 + 3] = std::numeric_limits<float>::quiet_NaN();
    x[32 + 15] = std::numeric_limits<float>::infinity();
    x[48 + 1] = 3e38f;  // finite, but its square overflows
    const auto out = c.classify(x);
    for (int r = 0; r < 4; ++r) {
      EXPECT_EQ(out[r].class_index, kNoClass) << r;
      EXPECT_EQ(out[r].score, 0.f);
      EXPECT_EQ(out[r].margin, 0.f);
    }
    EXPECT_NE(out[4].class_index, kNoClass);
    EXPECT_NE(out[4].class_index, 5);
  }
}

TEST(QueryClassifier, SameAnswerForAnyThreadCountAndScale) {
  const QuerySet q = random_queries(6, 512, 11, {5});
  const QueryClassifier c(q);
  auto x = random_embeddings(20000, 512, 12);
  const auto parallel = c.classify(x);
  std::vector<QueryMatch> serial;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    serial = c.classify(x);
  }
  ASSERT_EQ(parallel.size(), serial.size());
  EXPECT_EQ(std::memcmp(parallel.data(), serial.data(), parallel.size() * sizeof(QueryMatch)), 0);

  for (float& v : x) v *= 4.f;  // exact in binary: cosines are unchanged
  const auto scaled = c.classify(x);
  EXPECT_EQ(std::memcmp(parallel.data(), scaled.data(), parallel.size() * sizeof(QueryMatch)), 0);
}

TEST(QueryClassifier, RefusesRaggedInputAndBadQueries) {
  const QueryClassifier c(random_queries(2, 4, 1));
  EXPECT_NE(testing::error_of([&] { c.classify(std::vector<float>(6)); }).find("6 values are not whole 4-d"),
            std::string::npos);
  QuerySet bad = random_queries(2, 4, 1);
  bad.vectors(0, 0) = NAN;
  EXPECT_THROW(QueryClassifier{bad}, Error);
}

TEST(QueryClassifier, HugeOrTinyQueriesClassifyAsTheirDirection) {
  // Before: rows of 1e30 normalised in float became zero (every score 0).
  const QuerySet plain = random_queries(4, 16, 21);
  const std::vector<float> x = random_embeddings(64, 16, 22);
  const auto expected = QueryClassifier(plain).classify(x);
  for (const float scale : {1e30f, 1e-30f}) {
    QuerySet scaled = plain;
    scaled.vectors *= scale;
    const auto got = QueryClassifier(scaled).classify(x);
    ASSERT_EQ(got.size(), expected.size());
    for (std::size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].class_index, expected[i].class_index) << scale << " row " << i;
      EXPECT_NEAR(got[i].score, expected[i].score, 1e-5f) << scale << " row " << i;
    }
  }
}

}  // namespace
}  // namespace slamvdb

