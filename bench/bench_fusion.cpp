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
  Pose T_map_camera = bench::rellis_T_lidar_camera();
  FeatureMap features{512, 128, 192};

  explicit FusionSetup(EmbeddingPrecision precision) : map(make_params(precision)) {
    const auto scan = bench::benchmark_scan();
    for (int i = 0; i < 3; ++i) map.integrate_scan(scan, Pose::Identity());
    std::mt19937 rng(1);
    std::normal_distribution<float> g;
    for (float& v : features.data) v = g(rng);
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
  for (auto _ : state) stats = fusion.fuse(s.map, s.features, s.camera, s.T_map_camera);
  state.counters["voxels"] = static_cast<double>(stats.fused_voxels);
  state.counters["candidates"] = static_cast<double>(stats.candidates);
  state.counters["pixels"] = static_cast<double>(stats.pixels_used);
  state.SetLabel(to_string(static_cast<EmbeddingPrecision>(state.range(0))).data());
}
BENCHMARK(BM_FuseFeatureMap)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_AssociateOnly(benchmark::State& state) {
  FusionSetup s(EmbeddingPrecision::kFloat16);
  ProjectiveFusion fusion;
  for (auto _ : state) benchmark::DoNotOptimize(fusion.associate(s.map.occupancy(), s.camera, s.T_map_camera));
}
BENCHMARK(BM_AssociateOnly)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace slamvdb
