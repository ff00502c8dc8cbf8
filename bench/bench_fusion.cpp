// Fusing one 512 x 128 x 192 feature map (the paper's LSeg output size) into a map built from the
// real RELLIS-3D scan, seen through the real RELLIS-3D camera calibration.
#include <benchmark/benchmark.h>

#include <fmt/format.h>

#include <random>

#include "bench_data.hpp"
#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/fusion/projective_fusion.hpp"

namespace slamvdb {
namespace {

struct FusionSetup {
  VoxelMap map;
  CameraModel camera = bench::rellis_camera().scaled(192, 128);
  Pose T_submap_camera = bench::rellis_T_lidar_camera();
  FeatureMap features{512, 128, 192};
  FeatureMap half_features;  // the same values rounded to fp16, as a half-precision network gives them

  // drive_m > 0: the scan is also inserted every 5 m along a drive of that length ending at the
  // camera, so the map is large and the camera sees only its end (fusion must not scale with it).
  explicit FusionSetup(EmbeddingPrecision precision, double drive_m = 0) : map(make_params(precision)) {
    const auto scan = bench::benchmark_scan();
    for (double x = -drive_m; x < 0; x += 5.0) map.integrate_scan(scan, Pose(Eigen::Translation3d(x, 0.3 * x, 0)));
    for (int i = 0; i < 3; ++i) map.integrate_scan(scan, Pose::Identity());
    std::mt19937 rng(1);
    std::normal_distribution<float> g;
    for (float& v : features.values()) v = g(rng);
    half_features = features.converted(EmbeddingPrecision::kFloat16);
  }
  static MapParams make_params(EmbeddingPrecision precision) {
    MapParams p;
    p.semantic.precision = precision;
    return p;
  }
};

// Arguments: the map's embedding storage, then the feature map's precision (0 fp32, 1 fp16), then
// the fusion rule (0 paper, 1 quality: per-pixel weights, depth edges, and the statistics'
// weighted update). fp16 features are read as they are and widened in registers: half the bytes of
// the 50 MB fp32 map.
void BM_FuseFeatureMap(benchmark::State& state) {
  const auto storage = static_cast<EmbeddingPrecision>(state.range(0));
  const auto feature_precision = static_cast<EmbeddingPrecision>(state.range(1));
  const FusionWeighting rule = state.range(2) == 1 ? FusionWeighting::kQuality : FusionWeighting::kPaper;
  FusionSetup s(storage);
  const FeatureMap& features = feature_precision == EmbeddingPrecision::kFloat16 ? s.half_features : s.features;
  FusionParams params;
  params.weighting = rule;
  ProjectiveFusion fusion(params);
  FusionStats stats;
  for (auto _ : state) stats = fusion.fuse(s.map, features, s.camera, s.T_submap_camera);
  state.counters["voxels"] = static_cast<double>(stats.fused_voxels);
  state.counters["candidates"] = static_cast<double>(stats.candidates);
  state.counters["pixels"] = static_cast<double>(stats.pixels_used);
  state.counters["feature_MB"] = static_cast<double>(features.bytes()) / 1e6;
  state.SetLabel(
      fmt::format("map {}, features {}, {}", to_string(storage), to_string(feature_precision), to_string(rule)));
}
BENCHMARK(BM_FuseFeatureMap)
    ->ArgNames({"map_fp16", "features_fp16", "quality"})
    ->Args({1, 0, 0})
    ->Args({1, 1, 0})
    ->Args({0, 0, 0})
    ->Args({0, 1, 0})
    ->Args({1, 0, 1})
    ->Args({1, 1, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_FuseFeatureMapLargeMap(benchmark::State& state) {
  FusionSetup s(EmbeddingPrecision::kFloat16, 500.0);
  ProjectiveFusion fusion;
  FusionStats stats;
  for (auto _ : state) stats = fusion.fuse(s.map, s.features, s.camera, s.T_submap_camera);
  state.counters["voxels"] = static_cast<double>(stats.fused_voxels);
  state.counters["map_blocks"] = static_cast<double>(s.map.occupancy().num_blocks());
}
BENCHMARK(BM_FuseFeatureMapLargeMap)->Unit(benchmark::kMillisecond)->UseRealTime();

// One voxel's update, 512-d: Eq. 6.1's running mean alone (0) against the same update that also
// returns the squared distance West's update of the spread needs (1), fp16 storage (the default)
// and fp32: the cost of keeping the statistics.
void BM_SemanticIntegrate(benchmark::State& state) {
  constexpr std::size_t kDim = 512, kVoxels = 4096;  // 4 MB of fp16 voxels: beyond L2, as in a map
  const bool with_spread = state.range(0) == 1, half = state.range(1) == 1;
  std::vector<float> x(kDim), mean32(kVoxels * kDim, 0.f);
  std::vector<uint16_t> mean16(kVoxels * kDim, 0);
  std::mt19937 rng(2);
  std::normal_distribution<float> g;
  for (float& v : x) v = g(rng);
  std::size_t i = 0;
  float spread = 0;
  for (auto _ : state) {
    const std::size_t at = (i++ % kVoxels) * kDim;
    const float w = 1.0f / static_cast<float>(i / kVoxels + 1);
    if (with_spread)
      spread += half ? kernels::running_mean_sq(mean16.data() + at, x.data(), w, kDim)
                     : kernels::running_mean_sq(mean32.data() + at, x.data(), w, kDim);
    else if (half)
      kernels::running_mean(mean16.data() + at, x.data(), w, kDim);
    else
      kernels::running_mean(mean32.data() + at, x.data(), w, kDim);
  }
  benchmark::DoNotOptimize(spread);
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()));
  state.SetLabel(fmt::format("{}, {}", with_spread ? "running_mean_sq (mean + West's spread)" : "running_mean (Eq. 6.1)",
                             half ? "fp16" : "fp32"));
}
BENCHMARK(BM_SemanticIntegrate)->ArgNames({"spread", "fp16"})->ArgsProduct({{0, 1}, {1, 0}});

void BM_AssociateOnly(benchmark::State& state) {
  FusionSetup s(EmbeddingPrecision::kFloat16);
  ProjectiveFusion fusion;
  for (auto _ : state) benchmark::DoNotOptimize(fusion.associate(s.map.occupancy(), s.camera, s.T_submap_camera));
}
BENCHMARK(BM_AssociateOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace slamvdb
