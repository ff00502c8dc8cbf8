// Fusing one 512 x 128 x 192 feature map (the paper's LSeg output size) into a map built from the
// real RELLIS-3D scan, seen through the real RELLIS-3D camera calibration.
#include <benchmark/benchmark.h>

#include <fmt/format.h>

#include <random>

#include "bench_data.hpp"
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

// Arguments: the map's embedding storage, then the feature map's precision (0 fp32, 1 fp16). fp16
// features are read as they are and widened in registers: half the bytes of the 50 MB fp32 map.
void BM_FuseFeatureMap(benchmark::State& state) {
  const auto storage = static_cast<EmbeddingPrecision>(state.range(0));
  const auto feature_precision = static_cast<EmbeddingPrecision>(state.range(1));
  FusionSetup s(storage);
  const FeatureMap& features = feature_precision == EmbeddingPrecision::kFloat16 ? s.half_features : s.features;
  ProjectiveFusion fusion;
  FusionStats stats;
  for (auto _ : state) stats = fusion.fuse(s.map, features, s.camera, s.T_submap_camera);
  state.counters["voxels"] = static_cast<double>(stats.fused_voxels);
  state.counters["candidates"] = static_cast<double>(stats.candidates);
  state.counters["pixels"] = static_cast<double>(stats.pixels_used);
  state.counters["feature_MB"] = static_cast<double>(features.bytes()) / 1e6;
  state.SetLabel(fmt::format("map {}, features {}", to_string(storage), to_string(feature_precision)));
}
BENCHMARK(BM_FuseFeatureMap)
    ->ArgNames({"map_fp16", "features_fp16"})
    ->Args({1, 0})
    ->Args({1, 1})
    ->Args({0, 0})
    ->Args({0, 1})
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

void BM_AssociateOnly(benchmark::State& state) {
  FusionSetup s(EmbeddingPrecision::kFloat16);
  ProjectiveFusion fusion;
  for (auto _ : state) benchmark::DoNotOptimize(fusion.associate(s.map.occupancy(), s.camera, s.T_submap_camera));
}
BENCHMARK(BM_AssociateOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace slamvdb
