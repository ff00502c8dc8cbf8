// Fusing one 512 x 128 x 192 feature map (the paper's LSeg output size) into a map built from the
// real RELLIS-3D scan, seen through the real RELLIS-3D camera calibration.
#include <benchmark/benchmark.h>

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

  // drive_m > 0: the scan is also inserted every 5 m along a drive of that length ending at the
  // camera, so the map is large and the camera sees only its end (fusion must not scale with it).
  explicit FusionSetup(EmbeddingPrecision precision, double drive_m = 0) : map(make_params(precision)) {
    const auto scan = bench::benchmark_scan();
    for (double x = -drive_m; x < 0; x += 5.0) map.integrate_scan(scan, Pose(Eigen::Translation3d(x, 0.3 * x, 0)));
    for (int i = 0; i < 3; ++i) map.integrate_scan(scan, Pose::Identity());
    std::mt19937 rng(1);
    std::normal_distribution<float> g;
    for (float& v : features.values()) v = g(rng);
  }
  static MapParams make_params(EmbeddingPrecision precision) {
    MapParams p;
    p.semantic.precision = precision;
    return p;
  }
};

void BM_FuseFeatureMap(benchmark::State& state) {
  FusionSetup s(static_cast<EmbeddingPrecision>(state.range(0)));
  ProjectiveFusion fusion;
  FusionStats stats;
  for (auto _ : state) stats = fusion.fuse(s.map, s.features, s.camera, s.T_submap_camera);
  state.counters["voxels"] = static_cast<double>(stats.fused_voxels);
  state.counters["candidates"] = static_cast<double>(stats.candidates);
  state.counters["pixels"] = static_cast<double>(stats.pixels_used);
  state.SetLabel(to_string(static_cast<EmbeddingPrecision>(state.range(0))).data());
}
BENCHMARK(BM_FuseFeatureMap)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

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
