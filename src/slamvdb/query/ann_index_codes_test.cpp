// The ANN index's codes (ann_index_codes.hpp): every nibble kernel this CPU runs (AVX-512 VNNI,
// AVX2, scalar: chosen at run time, so CI machines without AVX-512 run the others) gives the same
// integers as the plain sum over dimensions; codes split into two planes join back to the 8-bit
// code; the weights' integer scores are the question's dot product with the decoded vector.
#include "slamvdb/query/ann_index_codes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace slamvdb::ann_codes {
namespace {

// Dimension d's nibble of a plane, from the packing's definition (not from the kernels' loops).
int nibble_of(const uint8_t* plane, std::size_t d) {
  const uint8_t byte = plane[d / 128 * 64 + d % 64];
  return (d % 128) < 64 ? (byte & 15) : (byte >> 4);
}

TEST(AnnCodes, EveryNibbleKernelOfThisCpuGivesThePlainSumOverDimensions) {
  std::mt19937 rng(3);
  for (const std::size_t plane_bytes : {std::size_t{64}, std::size_t{256}, std::size_t{384}}) {
    const std::size_t count = 37, dims = 2 * plane_bytes;
    std::vector<uint8_t> planes(count * plane_bytes);
    for (uint8_t& b : planes) b = static_cast<uint8_t>(rng());
    // The extremes too: every nibble 15 against weights of -128 and 127 (no 16-bit saturation).
    std::fill(planes.begin(), planes.begin() + static_cast<std::ptrdiff_t>(2 * plane_bytes), uint8_t{0xFF});
    std::vector<int8_t> weights(dims);
    for (std::size_t d = 0; d < dims; ++d) weights[d] = static_cast<int8_t>(static_cast<int>(rng() % 256) - 128);
    std::vector<int8_t> extreme(dims);
    for (std::size_t d = 0; d < dims; ++d) extreme[d] = (d / 3) % 2 ? int8_t{127} : int8_t{-128};
    for (const auto* w : {&weights, &extreme}) {
      std::vector<int32_t> expected(count);
      for (std::size_t i = 0; i < count; ++i)
        for (std::size_t d = 0; d < dims; ++d) expected[i] += nibble_of(planes.data() + i * plane_bytes, d) * (*w)[d];
      std::size_t ran = 0;
      for (const NibbleKernel& k : nibble_kernels()) {
        if (!k.supported) continue;
        std::vector<int32_t> out(count, -1);
        k.score(planes.data(), count, plane_bytes, w->data(), out.data());
        EXPECT_EQ(out, expected) << k.name << ", " << plane_bytes << " bytes per plane";
        ++ran;
      }
      EXPECT_GE(ran, 1u);
      for (const NibbleKernel& k : nibble_kernels()) {
        if (!k.supported || w != &weights) continue;
        std::vector<uint8_t> code(dims);
        for (std::size_t i = 0; i < count; i += 5) {  // the coarse and fine planes of a code: two planes here
          k.join(planes.data() + i * plane_bytes, planes.data() + (count - 1 - i) * plane_bytes, plane_bytes, code.data());
          for (std::size_t d = 0; d < dims; ++d)
            ASSERT_EQ(code[d], nibble_of(planes.data() + i * plane_bytes, d) * 16 +
                                   nibble_of(planes.data() + (count - 1 - i) * plane_bytes, d))
                << k.name << " dimension " << d;
        }
      }
      std::vector<int32_t> dispatched(count);
      score_nibbles(planes.data(), count, plane_bytes, w->data(), dispatched.data());
      EXPECT_EQ(dispatched, expected);
    }
  }
}

TEST(AnnCodes, PlanesJoinToTheByteCodeAndScoresAreTheDotProductWithTheDecodedVector) {
  constexpr std::size_t kDim = 200;  // not a multiple of 128: the padding scores nothing
  std::mt19937 rng(5);
  std::normal_distribution<float> gauss(0.f, 0.1f);
  std::vector<float> rows(64 * kDim);
  for (float& x : rows) x = gauss(rng);
  const Sq8Codebook book(rows.data(), 64, kDim);
  ASSERT_EQ(book.stride(), 256u);
  ASSERT_EQ(book.plane_bytes(), 128u);
  std::vector<float> q(kDim);
  for (float& x : q) x = gauss(rng);
  const QueryWeights w = book.weights(q.data());
  // low[d] and step[d] of the codebook, as the rows' ranges.
  std::vector<float> low(kDim), step(kDim);
  for (std::size_t d = 0; d < kDim; ++d) {
    float lo = rows[d], hi = rows[d];
    for (std::size_t i = 1; i < 64; ++i) lo = std::min(lo, rows[i * kDim + d]), hi = std::max(hi, rows[i * kDim + d]);
    low[d] = lo;
    step[d] = (hi - lo) / 255.f;
  }
  // The bound a list is skipped by: the code with nibble 15 where the weight is positive, 0 elsewhere.
  std::vector<uint8_t> best_plane(128, 0);
  for (std::size_t d = 0; d < kDim; ++d)
    if (w.coarse[d] > 0) best_plane[d / 128 * 64 + d % 64] |= static_cast<uint8_t>(15u << ((d % 128) < 64 ? 0 : 4));
  int32_t best_score = 0;
  score_nibbles(best_plane.data(), 1, 128, w.coarse.data(), &best_score);
  EXPECT_FLOAT_EQ(w.coarse_offset + w.coarse_unit * static_cast<float>(best_score), w.coarse_most);
  for (std::size_t i = 0; i < 64; ++i) {
    const float* x = rows.data() + i * kDim;
    std::vector<uint8_t> coarse(128), fine(128), code(256);
    book.encode(x, coarse.data(), fine.data());
    join_planes(coarse.data(), fine.data(), 128, code.data());
    double dot = 0, bound = 0;
    for (std::size_t d = 0; d < kDim; ++d) {
      EXPECT_NEAR(low[d] + step[d] * code[d], x[d], 0.5001 * step[d]) << d;
      EXPECT_EQ(nibble_of(coarse.data(), d), code[d] >> 4);
      dot += static_cast<double>(q[d]) * x[d];
      bound += std::abs(q[d]) * step[d];
    }
    for (std::size_t d = kDim; d < 256; ++d) EXPECT_EQ(code[d], 0);
    int32_t fine_score = 0, coarse_score = 0;
    score_codes(code.data(), 1, 256, w.fine.data(), &fine_score);
    score_nibbles(coarse.data(), 1, 128, w.coarse.data(), &coarse_score);
    // Fine: the code is within half a step per dimension (+ the weights' rounding, 1/8191 of the
    // largest). Coarse: a high nibble h stands for 16 h + 7.5, within 8 steps.
    EXPECT_NEAR(w.fine_offset + w.fine_unit * fine_score, dot, 0.51 * bound + 1e-3 * bound);
    const float coarse_value = w.coarse_offset + w.coarse_unit * static_cast<float>(coarse_score);
    EXPECT_NEAR(coarse_value, dot, 8.0 * bound + 0.05 * bound);
    EXPECT_LE(coarse_value, w.coarse_most) << "no code scores above the codebook's bound";
  }
}

}  // namespace
}  // namespace slamvdb::ann_codes
