// The global index and the map file: a full read of a million semantic cells, re-indexing after
// one submap moves against a full rebuild, and save / load of a map.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>

#include "bench_maps.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::bench {
namespace {

// Every cell read as a reader sees it: position, summed count and the count-weighted mean (a view
// into submap storage for single-entry cells, computed for shared ones).
void BM_IndexFullRead(benchmark::State& state) {
  const SemanticMap& map = indexed_map();
  std::size_t cells = 0, shared = 0;
  for (auto _ : state) {
    map.read_index([&](const GlobalIndex& index) {
      std::vector<float> scratch(512);
      uint64_t counts = 0;
      for (std::size_t i = 0; i < index.size(); ++i) {
        const IndexedVoxel v = index.read(i, scratch.data());
        counts += v.count;
        shared += v.entries > 1;
        benchmark::DoNotOptimize(v.embedding.data);
      }
      cells = index.size();
      benchmark::DoNotOptimize(counts);
    });
  }
  state.counters["cells"] = static_cast<double>(cells);
  state.counters["entries"] = static_cast<double>(map.num_semantic_voxels());
  state.counters["shared_cells"] = static_cast<double>(shared / state.iterations());
  state.counters["entries_per_s"] =
      benchmark::Counter(static_cast<double>(map.num_semantic_voxels()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_IndexFullRead)->Unit(benchmark::kMillisecond)->UseRealTime();

// A loop closure corrects one submap: only its 100 k entries are re-binned.
void BM_IndexMoveOneSubmap(benchmark::State& state) {
  SemanticMap& map = indexed_map();
  Pose T = map.submap_info(5)->T_world_submap;
  double dx = 0.01;
  for (auto _ : state) {
    T.translation().y() += dx;
    dx = -dx;
    map.set_submap_poses({{5, T}});
  }
  state.counters["entries_moved"] = kEntriesPerSubmap;
}
BENCHMARK(BM_IndexMoveOneSubmap)->Unit(benchmark::kMillisecond)->UseRealTime();

// The alternative: re-bin every submap (what a correction of all poses costs).
void BM_IndexRebuildAll(benchmark::State& state) {
  SemanticMap& map = indexed_map();
  std::map<int, Pose> poses;
  for (const SubmapInfo& s : map.submaps()) poses[s.id] = s.T_world_submap;
  double dx = 0.01;
  for (auto _ : state) {
    for (auto& [id, T] : poses) T.translation().y() += dx;
    dx = -dx;
    map.set_submap_poses(poses);
  }
  state.counters["entries_moved"] = kSubmaps * kEntriesPerSubmap;
}
BENCHMARK(BM_IndexRebuildAll)->Unit(benchmark::kMillisecond)->UseRealTime();

// Save and load: the map in $SLAMVDB_BENCH_MAP (e.g. the default sequence's map from
// scripts/demo.sh), else the indexed map above.
std::filesystem::path bench_map_file() {
  static const std::filesystem::path path = [] {
    if (const char* env = std::getenv("SLAMVDB_BENCH_MAP")) return std::filesystem::path(env);
    const auto p = std::filesystem::temp_directory_path() / ("slamvdb_bench_map_" + std::to_string(getpid()) + ".svdb");
    save_map(p, indexed_map());
    return p;
  }();
  return path;
}

void BM_LoadMap(benchmark::State& state) {
  const auto path = bench_map_file();
  for (auto _ : state) {
    const SemanticMap map = load_map(path);
    benchmark::DoNotOptimize(map.num_index_cells());
  }
  state.counters["MB"] = static_cast<double>(std::filesystem::file_size(path)) / 1e6;
}
BENCHMARK(BM_LoadMap)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

void BM_SaveMap(benchmark::State& state) {
  const SemanticMap map = load_map(bench_map_file());
  const auto out = std::filesystem::temp_directory_path() / ("slamvdb_bench_save_" + std::to_string(getpid()) + ".svdb");
  for (auto _ : state) save_map(out, map);
  std::filesystem::remove(out);
}
BENCHMARK(BM_SaveMap)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace
}  // namespace slamvdb::bench
