#include "slamvdb/core/embedding_kernels.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <vector>

#include "slamvdb/core/half.hpp"

namespace slamvdb {
namespace {

// Fusion's sums: adding fp16 values gives, bit for bit, the sums of their fp32 widenings, on the
// 8-wide path and its scalar tail alike (lengths 1 to 40).
TEST(EmbeddingKernels, AddingFp16EqualsAddingItsFp32Values) {
  std::mt19937 rng(3);
  std::normal_distribution<float> g;
  for (std::size_t n = 1; n <= 40; ++n) {
    std::vector<uint16_t> half(n);
    std::vector<float> wide(n), acc_half(n), acc_wide(n), acc_plain(n);
    for (int round = 0; round < 5; ++round) {
      for (std::size_t i = 0; i < n; ++i) {
        half[i] = float_to_half(g(rng) * 100.0f);
        wide[i] = half_to_float(half[i]);
      }
      kernels::add(acc_half.data(), {half.data(), EmbeddingPrecision::kFloat16}, n);
      kernels::add(acc_wide.data(), {wide.data(), EmbeddingPrecision::kFloat32}, n);
      for (std::size_t i = 0; i < n; ++i) acc_plain[i] += wide[i];
    }
    ASSERT_EQ(std::memcmp(acc_half.data(), acc_wide.data(), n * sizeof(float)), 0) << n;
    ASSERT_EQ(std::memcmp(acc_half.data(), acc_plain.data(), n * sizeof(float)), 0) << n;
  }
}

}  // namespace
}  // namespace slamvdb
