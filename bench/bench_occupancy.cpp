// Integrating one full scan: slamvdb's occupancy grid against OctoMap with the same resolution,
// ranges and log-odds parameters (the baseline).
#include <benchmark/benchmark.h>
#include <octomap/OcTree.h>
#include <tbb/global_control.h>

#include "bench_data.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {
namespace {

// OctoMap's insertPointCloud(maxrange) clears every ray up to maxrange and inserts only returns
// within it; slamvdb does the same when max_point_range == max_clearing_range.
OccupancyParams octomap_equivalent_params() {
  OccupancyParams p;
  p.voxel_size = 0.25;
  p.min_point_range = 0.0;
  p.max_point_range = 25.0;
  p.max_clearing_range = 25.0;
  return p;
}

Pose scan_pose(int i) {
  Pose T = Pose::Identity();
  T.translation() = Vec3d(0.5 * (i % 8), 0.1 * (i % 8), 0.0);  // a short drive, revisited
  return T;
}

// Scan argument: 0 = the synthetic scan, 1 = the real RELLIS-3D scan (skipped without the fixture).
std::vector<Vec3f> scan_or_skip(benchmark::State& state, int64_t which) {
  std::vector<Vec3f> scan = which == 0 ? bench::synthetic_scan() : bench::real_scan();
  if (scan.empty()) state.SkipWithError("no RELLIS-3D fixture in ../shared/fixtures");
  return scan;
}

// Arguments: worker threads (OctoMap's insertion is single-threaded), scan.
void BM_SlamvdbIntegrateScan(benchmark::State& state) {
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  const auto scan = scan_or_skip(state, state.range(1));
  if (scan.empty()) return;
  OccupancyGrid grid(octomap_equivalent_params());
  grid.integrate_scan(scan, scan_pose(0));  // steady state: the map already holds the area
  int i = 1;
  for (auto _ : state) benchmark::DoNotOptimize(grid.integrate_scan(scan, scan_pose(i++)));
  state.counters["points"] = static_cast<double>(scan.size());
  state.counters["points/s"] = benchmark::Counter(static_cast<double>(scan.size()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_SlamvdbIntegrateScan)->ArgsProduct({{1, 2}, {0, 1}})->ArgNames({"threads", "real"})->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SlamvdbVoxelMapIntegrateScan(benchmark::State& state) {  // with the semantic-erase hook
  const auto scan = bench::benchmark_scan();
  MapParams mp;
  mp.occupancy = octomap_equivalent_params();
  VoxelMap map(mp);
  map.integrate_scan(scan, scan_pose(0));
  int i = 1;
  for (auto _ : state) benchmark::DoNotOptimize(map.integrate_scan(scan, scan_pose(i++)));
}
BENCHMARK(BM_SlamvdbVoxelMapIntegrateScan)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_OctoMapInsertPointCloud(benchmark::State& state) {
  const auto scan = scan_or_skip(state, state.range(0));
  if (scan.empty()) return;
  const auto p = octomap_equivalent_params();
  octomap::OcTree tree(p.voxel_size);
  tree.setProbHit(0.7);
  tree.setProbMiss(0.4);
  tree.setClampingThresMin(0.1192);
  tree.setClampingThresMax(0.971);
  auto insert = [&](int i) {
    const Pose T = scan_pose(i);
    octomap::Pointcloud cloud;
    cloud.reserve(scan.size());
    for (const Vec3f& q : scan) {
      const Vec3d w = T * q.cast<double>();
      cloud.push_back(static_cast<float>(w.x()), static_cast<float>(w.y()), static_cast<float>(w.z()));
    }
    const Vec3d o = T.translation();
    tree.insertPointCloud(cloud, octomap::point3d(o.x(), o.y(), o.z()), p.max_point_range);
  };
  insert(0);
  int i = 1;
  for (auto _ : state) insert(i++);
  state.counters["points"] = static_cast<double>(scan.size());
}
BENCHMARK(BM_OctoMapInsertPointCloud)->Arg(0)->Arg(1)->ArgName("real")->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

}  // namespace
}  // namespace slamvdb
