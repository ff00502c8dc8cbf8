#include "slamvdb/training/query_trainer.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <random>

#include "slamvdb/testing/error_of.hpp"

namespace slamvdb {
namespace {

// Three classes around random unit centres with isotropic noise.
struct Blobs {
  QueryMatrix centres;
  PixelSamples samples{16};
};

Blobs blobs(std::size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  Blobs b;
  b.centres.resize(3, 16);
  std::mt19937 fixed(7);  // the same centres for every seed
  for (int i = 0; i < b.centres.size(); ++i) b.centres.data()[i] = std::normal_distribution<float>()(fixed);
  b.centres.rowwise().normalize();
  std::vector<float> x(16);
  for (std::size_t i = 0; i < n; ++i) {
    const int k = static_cast<int>(i % 3);
    for (int d = 0; d < 16; ++d) x[d] = b.centres(k, d) + 0.15f * g(rng);
    b.samples.append(x.data(), static_cast<int16_t>(k));
  }
  return b;
}

// Options with one field changed (designated initializers would warn about the others).
template <typename F>
TrainerOptions options(F change) {
  TrainerOptions o;
  change(o);
  return o;
}

double accuracy(const QueryMatrix& q, const PixelSamples& s) {
  std::vector<float> x(s.dim());
  std::size_t right = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    s.decode(i, 1, x.data());
    Eigen::Index best;
    (q * Eigen::Map<const Eigen::VectorXf>(x.data(), s.dim())).maxCoeff(&best);
    right += best == s.targets()[i];
  }
  return double(right) / s.size();
}

TEST(QueryTrainer, LowersTheLossAndFixesBadInitialQueries) {
  const Blobs train = blobs(3000, 1), val = blobs(900, 2);
  QueryMatrix wrong(3, 16);  // queries pointing at the wrong classes
  wrong.row(0) = train.centres.row(1);
  wrong.row(1) = train.centres.row(2);
  wrong.row(2) = train.centres.row(0);
  QueryTrainer trainer(wrong, options([](auto& o) { o.batch_size = 256, o.learning_rate = 0.05, o.seed = 3; }));
  const double loss0 = trainer.loss(val.samples);
  EXPECT_LT(accuracy(trainer.queries(), val.samples), 0.1);
  double previous = 1e9;
  for (int e = 0; e < 3; ++e) {
    const double l = trainer.train_epoch(train.samples);
    EXPECT_LT(l, previous);
    previous = l;
  }
  EXPECT_EQ(trainer.epochs_done(), 3);
  EXPECT_LT(trainer.loss(val.samples), 0.2 * loss0);
  EXPECT_GT(accuracy(trainer.queries(), val.samples), 0.99);
  EXPECT_NEAR(trainer.queries().row(0).norm(), 1.f, 1e-5f);
}

TEST(QueryTrainer, SameSeedSameVectors) {
  const Blobs train = blobs(2000, 4);
  const QueryMatrix init = QueryMatrix::Ones(3, 16);
  const auto run = [&](uint64_t seed) {
    QueryTrainer t(init, options([&](auto& o) { o.batch_size = 100, o.temperature = 0.1, o.seed = seed; }));
    t.train_epoch(train.samples);
    t.train_epoch(train.samples);
    return t.queries();
  };
  const QueryMatrix a = run(5), b = run(5), c = run(6);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(float) * a.size()), 0);
  EXPECT_NE(std::memcmp(a.data(), c.data(), sizeof(float) * a.size()), 0);  // the shuffle depends on the seed
}

TEST(QueryTrainer, RefusesBadOptionsAndData) {
  const QueryMatrix q = QueryMatrix::Ones(2, 4);
  using testing::error_of;
  EXPECT_NE(error_of([&] { QueryTrainer(q, options([](auto& o) { o.epochs = -1; })); }).find("epochs must be >= 0"), std::string::npos);
  EXPECT_NE(error_of([&] { QueryTrainer(q, options([](auto& o) { o.batch_size = 0; })); }).find("batch size"), std::string::npos);
  EXPECT_NE(error_of([&] { QueryTrainer(q, options([](auto& o) { o.learning_rate = -1; })); }).find("learning rate"), std::string::npos);
  EXPECT_NE(error_of([&] { QueryTrainer(q, options([](auto& o) { o.temperature = 0; })); }).find("temperature"), std::string::npos);
  EXPECT_NE(error_of([&] { QueryTrainer(QueryMatrix::Zero(2, 4), {}); }).find("initial query 0 is zero"),
            std::string::npos);
  QueryTrainer t(q, {});
  PixelSamples wrong_dim(5), empty(4), bad_target(4);
  const float x[5] = {1, 0, 0, 0, 0};
  wrong_dim.append(x, 0);
  bad_target.append(x, 2);
  EXPECT_NE(error_of([&] { t.train_epoch(wrong_dim); }).find("5-d samples for 4-d queries"), std::string::npos);
  EXPECT_NE(error_of([&] { t.train_epoch(empty); }).find("no training pixels"), std::string::npos);
  EXPECT_NE(error_of([&] { t.train_epoch(bad_target); }).find("target 2 is not one of the 2"), std::string::npos);
}

TEST(PixelSampling, UniformBalancedAndDeterministic) {
  FeatureMap f(4, 10, 10);
  std::vector<int> targets(100, -1);  // 20 ignored pixels
  for (int i = 0; i < 100; ++i) {
    for (int d = 0; d < 4; ++d) f.values()[i * 4 + d] = float(i + d);
    if (i >= 20) targets[i] = i < 90 ? 0 : 1;  // 70 of class 0, 10 of class 1
  }
  f.values()[25 * 4 + 0] = NAN;  // a broken feature: dropped, counted
  const auto count_of = [](const PixelSamples& s, int k) {
    return std::count(s.targets().begin(), s.targets().end(), k);
  };
  PixelSamples u(4), b(4), all(4);
  const SampleCounts cu = sample_pixels(f, targets, 20, PixelSampling::kUniform, 1, u);
  EXPECT_EQ(cu.labelled, 80u);
  EXPECT_EQ(cu.sampled + cu.bad, 20u);
  const SampleCounts cb = sample_pixels(f, targets, 20, PixelSampling::kClassBalanced, 1, b);
  EXPECT_EQ(count_of(b, 1), 10);  // even split, 10 each
  EXPECT_EQ(count_of(b, 0) + static_cast<long>(cb.bad), 10);
  const SampleCounts ca = sample_pixels(f, targets, 1000, PixelSampling::kUniform, 1, all);
  EXPECT_EQ(ca.sampled, 79u);  // every labelled pixel but the broken one
  EXPECT_EQ(ca.bad, 1u);
  EXPECT_EQ(count_of(all, -1), 0);

  // Deterministic per seed, different across seeds; rows are unit vectors.
  PixelSamples u2(4), u3(4);
  sample_pixels(f, targets, 20, PixelSampling::kUniform, 1, u2);
  sample_pixels(f, targets, 20, PixelSampling::kUniform, 2, u3);
  std::vector<float> a(u.size() * 4), a2(u2.size() * 4), a3(u3.size() * 4);
  u.decode(0, u.size(), a.data());
  u2.decode(0, u2.size(), a2.data());
  u3.decode(0, u3.size(), a3.data());
  EXPECT_EQ(a, a2);
  EXPECT_NE(a, a3);
  EXPECT_NEAR(Eigen::Map<const Eigen::Vector4f>(a.data()).norm(), 1.f, 1e-3f);
  EXPECT_THROW(sample_pixels(f, std::vector<int>(99), 5, PixelSampling::kUniform, 1, u), Error);
}

}  // namespace
}  // namespace slamvdb
