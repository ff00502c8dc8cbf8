// The world occupancy of a submapped map (SemanticMap::world_occupancy -> combine_occupancy): what
// `info --check`, export, nav grids and the map comparisons pay per read of a map.
#include <benchmark/benchmark.h>

#include "bench_data.hpp"
#include "slamvdb/map/submap_merge.hpp"

namespace slamvdb {
namespace {

// Eight overlapping submaps along a turning road, each three scans of the simulated scan (ground,
// walls, free space out to 25 m): ~0.3 M known voxels a submap, placed at yaws that are not
// multiples of 90 degrees, as on real drives.
struct WorldOccupancyBenchMaps {
  std::vector<VoxelMap> maps;
  std::vector<PlacedVoxelMap> placed;
  std::size_t known = 0;
};

const WorldOccupancyBenchMaps& world_occupancy_bench_maps() {
  static const WorldOccupancyBenchMaps data = [] {
    WorldOccupancyBenchMaps d;
    const std::vector<Vec3f> scan = bench::synthetic_scan();
    for (int s = 0; s < 8; ++s) {
      VoxelMap& m = d.maps.emplace_back(MapParams{});
      for (int i = 0; i < 3; ++i) {
        Pose T_submap_sensor = Pose::Identity();
        T_submap_sensor.translation() = Vec3d(4.0 * i, 0.3 * i, 0.0);
        m.integrate_scan(scan, T_submap_sensor);
      }
      d.known += m.occupancy().num_known_voxels();
    }
    for (int s = 0; s < 8; ++s) {
      Pose T = Pose::Identity();
      T.linear() = Eigen::AngleAxisd(0.23 * s, Vec3d::UnitZ()).toRotationMatrix();
      T.translation() = Vec3d(10.0 * s, 2.0 * s * s, 0.1 * s);
      d.placed.push_back({&d.maps[s], T});
    }
    return d;
  }();
  return data;
}

void BM_CombineOccupancy(benchmark::State& state) {
  const WorldOccupancyBenchMaps& d = world_occupancy_bench_maps();
  std::size_t cells = 0;
  for (auto _ : state) {
    const auto world = combine_occupancy(d.placed, 0.25, OccupancyParams{});
    cells = world.size();
    benchmark::DoNotOptimize(world.data());
  }
  state.counters["known_voxels"] = static_cast<double>(d.known);
  state.counters["world_cells"] = static_cast<double>(cells);
  state.counters["voxels/s"] = benchmark::Counter(static_cast<double>(d.known), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_CombineOccupancy)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace slamvdb
