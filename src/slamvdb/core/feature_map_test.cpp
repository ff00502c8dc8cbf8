#include "slamvdb/core/feature_map.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"

namespace slamvdb {
namespace {

TEST(FeatureMap, HoldsEitherPrecisionBehindTypedAccessors) {
  FeatureMap f(3, 2, 4);
  EXPECT_EQ(f.precision(), EmbeddingPrecision::kFloat32);
  EXPECT_EQ(f.pixels(), 8u);
  EXPECT_EQ(f.size(), 24u);
  EXPECT_EQ(f.bytes(), 96u);
  for (float v : f.values()) EXPECT_EQ(v, 0.0f);  // zero-filled
  f.pixel(3, 1)[2] = 5.5f;
  EXPECT_EQ(f.values()[(1 * 4 + 3) * 3 + 2], 5.5f);
  EXPECT_THROW(f.half_values(), Error);
  EXPECT_THROW(f.half_pixel(0, 0), Error);

  FeatureMap h(3, 2, 4, EmbeddingPrecision::kFloat16);
  EXPECT_EQ(h.bytes(), 48u);
  for (uint16_t v : h.half_values()) EXPECT_EQ(v, 0u);
  h.half_pixel(3, 1)[2] = float_to_half(5.5f);
  EXPECT_THROW(h.values(), Error);
  EXPECT_THROW(h.pixel(0, 0), Error);
  float decoded[3];
  h.decode_pixel(3, 1, decoded);
  EXPECT_EQ(decoded[2], 5.5f);
  EXPECT_EQ(static_cast<const uint16_t*>(h.view(7).data)[2], float_to_half(5.5f));
  EXPECT_EQ(h.view(7).precision, EmbeddingPrecision::kFloat16);

  EXPECT_EQ(h.converted(EmbeddingPrecision::kFloat32), f);  // 5.5 is exact in fp16
  EXPECT_EQ(f.converted(EmbeddingPrecision::kFloat16), h);
  EXPECT_NE(f, FeatureMap(3, 2, 4, EmbeddingPrecision::kFloat16));  // precision is part of the value
  EXPECT_THROW(FeatureMap(-1, 2, 2), Error);
}

TEST(FeatureMap, ResetSwitchesPrecisionAndReleasesTheOtherBuffer) {
  FeatureMap f(8, 4, 4);
  const float* storage = f.values().data();
  f.reset(8, 2, 4);  // smaller, same precision: the same buffer
  EXPECT_EQ(f.values().data(), storage);
  EXPECT_EQ(f.size(), 64u);
  f.reset(8, 4, 4, EmbeddingPrecision::kFloat16);
  EXPECT_EQ(f.precision(), EmbeddingPrecision::kFloat16);
  EXPECT_EQ(f.half_values().size(), 128u);
  EXPECT_EQ(f.bytes(), 256u);
  f.reset(0, 0, 0);
  EXPECT_TRUE(f.empty());
}

// fp16 -> fp32 -> fp16 returns every non-NaN bit pattern (widening is exact), and fp32 -> fp16
// rounds to nearest even, through the whole-map conversion the benchmark and tests use.
TEST(FeatureMap, ConversionIsExactOneWayAndRoundsTheOther) {
  FeatureMap all(1, 256, 256, EmbeddingPrecision::kFloat16);
  for (std::size_t i = 0; i < all.size(); ++i) all.half_values()[i] = static_cast<uint16_t>(i);
  const FeatureMap wide = all.converted(EmbeddingPrecision::kFloat32);
  const FeatureMap back = wide.converted(EmbeddingPrecision::kFloat16);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const uint16_t h = static_cast<uint16_t>(i);
    const bool nan = (h & 0x7c00u) == 0x7c00u && (h & 0x3ffu) != 0;
    if (nan) {
      EXPECT_TRUE(std::isnan(wide.values()[i]));
      continue;
    }
    ASSERT_EQ(wide.values()[i], half_to_float(h)) << i;
    ASSERT_EQ(back.half_values()[i], h) << i;
  }
  FeatureMap f(1, 1, 2);
  f.values()[0] = 1.0f + 1.0f / 2048;  // halfway between 1 and the next fp16: to even (1)
  f.values()[1] = 1e6f;                // beyond fp16: Inf, which fusion counts as non-finite
  const FeatureMap h = f.converted(EmbeddingPrecision::kFloat16);
  EXPECT_EQ(h.half_values()[0], 0x3c00u);
  EXPECT_EQ(h.half_values()[1], 0x7c00u);
}

}  // namespace
}  // namespace slamvdb
