// Retrieval over a map of a million semantic voxels (512-d fp16) through the global index:
// top-k similarity of one query, and classification against six query vectors.
#include <benchmark/benchmark.h>

#include "bench_maps.hpp"
#include "slamvdb/query/map_query.hpp"

namespace slamvdb::bench {
namespace {

// Arg 0: the road map (1.06 M cells, a fifth shared by two submaps); 1: 1.0 M single-entry cells.
const SemanticMap& bench_map(const benchmark::State& state) { return state.range(0) ? disjoint_map() : indexed_map(); }

void BM_QueryTopK(benchmark::State& state) {
  const SemanticMap& map = bench_map(state);
  Eigen::VectorXf q = Eigen::VectorXf::Zero(512);
  q[3] = 1.0f, q[7] = 0.5f;
  SearchOptions options;
  options.top_k = 100;
  for (auto _ : state) benchmark::DoNotOptimize(similarity_search(map, {q.data(), 512}, options).size());
  state.counters["cells"] = static_cast<double>(map.num_index_cells());
  state.counters["cells_per_s"] =
      benchmark::Counter(static_cast<double>(map.num_index_cells()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_QueryTopK)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ClassifyMap(benchmark::State& state) {
  const SemanticMap& map = bench_map(state);
  QuerySet queries;
  queries.model_id = map.info().model_id.empty() ? "bench" : map.info().model_id;
  queries.names = {"smooth", "rough", "bumpy", "obstacle", "active", "void"};
  queries.vectors = QueryMatrix::Zero(6, 512);
  for (int k = 0; k < 6; ++k) queries.vectors(k, k) = 1.0f;
  queries.void_classes = {5};
  for (auto _ : state)
    benchmark::DoNotOptimize(classify_map(map, queries, {}, ModelIdCheck::kIgnore).size());
  state.counters["cells"] = static_cast<double>(map.num_index_cells());
}
BENCHMARK(BM_ClassifyMap)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace slamvdb::bench
