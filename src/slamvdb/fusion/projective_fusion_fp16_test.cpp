// Fusion reading fp16 feature maps (as half-precision networks and '<f2' files give them) must do
// exactly what it does with the same values in fp32: widening fp16 is exact, and the sums run in
// fp32 in the same order either way.
#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"
#include "slamvdb/fusion/projective_fusion.hpp"
#include "slamvdb/testing/fusion_fixtures.hpp"

namespace slamvdb {
namespace {

CameraModel fp16_test_camera() { return testing::centred_camera(96, 64); }

// A bumpy wall in front of the camera and a few voxels before it: many voxels, partial occlusion.
std::vector<Vec3d> fp16_test_scene() {
  std::vector<Vec3d> points;
  for (double x = -3; x <= 3; x += 0.25)
    for (double y = -2; y <= 2; y += 0.25) points.emplace_back(x, y, 6.0 + 0.5 * std::sin(x) * std::cos(y));
  for (double x = -1; x <= 1; x += 0.5) points.emplace_back(x, 0.3 * x, 3.0);
  return points;
}

VoxelMap fp16_test_map(int dim, EmbeddingPrecision storage) {
  VoxelMap map(testing::fusion_map_params(dim, storage));
  for (const Vec3d& p : fp16_test_scene()) map.occupancy().set_log_odds(map.occupancy().key_of(p), 2.0f);
  return map;
}

// Random fp16 features (values of all magnitudes fp16 holds, subnormals included).
FeatureMap random_half_features(int dim, uint32_t seed) {
  const CameraModel c = fp16_test_camera();
  FeatureMap f(dim, c.height, c.width, EmbeddingPrecision::kFloat16);
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  std::uniform_int_distribution<int> exponent(-20, 8);
  for (uint16_t& h : f.half_values()) h = float_to_half(g(rng) * std::ldexp(1.0f, exponent(rng)));
  return f;
}

// Every voxel of the scene: same count, bit-identical embedding.
void expect_same_semantics(const VoxelMap& a, const VoxelMap& b, int dim) {
  std::size_t found = 0;
  std::vector<float> va(dim), vb(dim);
  for (const Vec3d& p : fp16_test_scene()) {
    const VoxelKey key = a.occupancy().key_of(p);
    const auto sa = a.semantics().find(key), sb = b.semantics().find(key);
    ASSERT_EQ(sa.has_value(), sb.has_value());
    if (!sa) continue;
    ++found;
    ASSERT_EQ(a.semantics().count_of(*sa), b.semantics().count_of(*sb));
    a.semantics().read(*sa, va.data());
    b.semantics().read(*sb, vb.data());
    ASSERT_EQ(std::memcmp(va.data(), vb.data(), sizeof(float) * dim), 0) << "voxel at " << p.transpose();
  }
  EXPECT_GT(found, 100u);
}

void expect_same_stats(const FusionStats& a, const FusionStats& b) {
  EXPECT_EQ(a.candidates, b.candidates);
  EXPECT_EQ(a.fused_voxels, b.fused_voxels);
  EXPECT_EQ(a.occluded, b.occluded);
  EXPECT_EQ(a.pixels_used, b.pixels_used);
  EXPECT_EQ(a.pixels_total, b.pixels_total);
  EXPECT_EQ(a.pixels_nonfinite, b.pixels_nonfinite);
  EXPECT_EQ(a.pixels_zero, b.pixels_zero);
  EXPECT_EQ(a.frames_refused_invalid, b.frames_refused_invalid);
}

// Fuses the fp16 frames into one map and their exact fp32 widenings into another, frame by frame.
void fuse_both_ways(const std::vector<FeatureMap>& half_frames, int dim, EmbeddingPrecision storage,
                    std::vector<FusionStats>* stats_half = nullptr) {
  VoxelMap from_half = fp16_test_map(dim, storage), from_float = fp16_test_map(dim, storage);
  ProjectiveFusion fusion_half, fusion_float;
  Pose T = Pose::Identity();
  for (const FeatureMap& half : half_frames) {
    const FeatureMap widened = half.converted(EmbeddingPrecision::kFloat32);
    ASSERT_EQ(widened.precision(), EmbeddingPrecision::kFloat32);
    const FusionStats a = fusion_half.fuse(from_half, half, fp16_test_camera(), T);
    const FusionStats b = fusion_float.fuse(from_float, widened, fp16_test_camera(), T);
    expect_same_stats(a, b);
    if (stats_half) stats_half->push_back(a);
    T.translation() += Vec3d(0.07, -0.03, 0.1);  // the next frame sees the voxels a little differently
  }
  expect_same_semantics(from_half, from_float, dim);
}

TEST(ProjectiveFusionFp16, EqualsFusingTheSameValuesInFp32) {
  // 37: not a multiple of the 8-wide conversion (the tail path); 64: only full vectors.
  for (const int dim : {37, 64}) {
    for (const EmbeddingPrecision storage : {EmbeddingPrecision::kFloat32, EmbeddingPrecision::kFloat16}) {
      SCOPED_TRACE(::testing::Message() << "dim " << dim << ", storage " << static_cast<int>(storage));
      std::vector<FusionStats> stats;
      fuse_both_ways({random_half_features(dim, 1), random_half_features(dim, 2), random_half_features(dim, 3)}, dim,
                     storage, &stats);
      ASSERT_EQ(stats.size(), 3u);
      EXPECT_GT(stats[0].fused_voxels, 100u);
      EXPECT_GT(stats[0].occluded, 0u);
      EXPECT_EQ(stats[0].pixels_nonfinite + stats[0].pixels_zero, 0u);
    }
  }
}

// NaN, +-Inf and all-zero (+0 or -0) pixels are skipped and counted as for fp32 features.
TEST(ProjectiveFusionFp16, NonFinitePixelsAreCountedAsInFp32) {
  const int dim = 37;
  FeatureMap damaged = random_half_features(dim, 4);
  const uint16_t kNan = 0x7e00, kInf = 0x7c00, kMinusInf = 0xfc00, kMinusZero = 0x8000;
  const uint16_t bad[] = {kNan, kInf, kMinusInf};
  int k = 0;
  for (int y = 0; y < damaged.height(); y += 3)
    for (int x = 0; x < damaged.width(); x += 4, ++k) {
      uint16_t* p = damaged.half_pixel(x, y);
      if (k % 4 == 3) std::fill_n(p, dim, k % 8 == 3 ? uint16_t{0} : kMinusZero);
      else p[(k * 7) % dim] = bad[k % 4];
    }
  std::vector<FusionStats> stats;
  fuse_both_ways({random_half_features(dim, 5), damaged, random_half_features(dim, 6)}, dim,
                 EmbeddingPrecision::kFloat16, &stats);
  ASSERT_EQ(stats.size(), 3u);
  EXPECT_GT(stats[1].pixels_nonfinite, 50u);
  EXPECT_GT(stats[1].pixels_zero, 10u);
  EXPECT_EQ(stats[1].frames_refused_invalid, 0u);

  // A frame mostly NaN (fp16 overflow everywhere) is refused whole, as in fp32, and changes nothing.
  FeatureMap flooded = random_half_features(dim, 7);
  for (uint16_t& h : flooded.half_values()) h = kInf;
  stats.clear();
  fuse_both_ways({random_half_features(dim, 8), flooded}, dim, EmbeddingPrecision::kFloat16, &stats);
  ASSERT_EQ(stats.size(), 2u);
  EXPECT_EQ(stats[1].frames_refused_invalid, 1u);
  EXPECT_EQ(stats[1].fused_voxels, 0u);
}

TEST(ProjectiveFusionFp16, RejectsMismatchedFp16FeatureMaps) {
  VoxelMap map = fp16_test_map(8, EmbeddingPrecision::kFloat16);
  ProjectiveFusion fusion;
  const CameraModel c = fp16_test_camera();
  EXPECT_THROW(fusion.fuse(map, FeatureMap(7, c.height, c.width, EmbeddingPrecision::kFloat16), c, Pose::Identity()),
               Error);
  EXPECT_THROW(fusion.fuse(map, FeatureMap(8, c.height, c.width + 1, EmbeddingPrecision::kFloat16), c, Pose::Identity()),
               Error);
}

}  // namespace
}  // namespace slamvdb
