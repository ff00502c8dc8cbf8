// Classifying voxel embeddings against a query set (paper section 6.3: 6 coarse terrain classes,
// 512-d LSeg embeddings), 1 M rows per iteration.
//   Arg 0: kernel, 0 = chosen at run time (AVX2 + FMA here), 1 = portable Eigen kernel.
//   Arg 1: threads (TBB).
//   BM_QueryClassifyStream: 1 M x 512 fp32 rows from one 2 GB buffer (bound by memory bandwidth).
//   BM_QueryClassifyResident: 1 M rows as 4096-row chunks whose data sit in cache, as when the map
//     side decodes its fp16 chunks into an fp32 buffer and classifies each chunk.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <random>
#include <vector>

#include "slamvdb/query/query_classifier.hpp"

namespace {

using namespace slamvdb;

constexpr int kDim = 512;
constexpr std::size_t kRows = 1 << 20;
constexpr std::size_t kChunkRows = 4096;

QuerySet six_queries() {
  std::mt19937 rng(1);
  std::normal_distribution<float> g;
  QuerySet q;
  q.model_id = "bench";
  q.names = {"smooth", "rough", "bumpy", "obstacle", "active", "void"};
  q.vectors.resize(6, kDim);
  for (int i = 0; i < q.vectors.size(); ++i) q.vectors.data()[i] = g(rng);
  q.void_classes = {5};
  return q;
}

std::vector<float> random_rows(std::size_t rows) {
  std::vector<float> x(rows * kDim);
  tbb::parallel_for(std::size_t{0}, rows, [&](std::size_t r) {
    std::mt19937 rng(static_cast<uint32_t>(r));
    std::normal_distribution<float> g;
    for (int d = 0; d < kDim; ++d) x[r * kDim + d] = g(rng);
  });
  return x;
}

void BM_QueryClassifyStream(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(1));
  const QueryClassifier classifier(six_queries(), {.portable_kernel = state.range(0) == 1});
  static const std::vector<float> x = random_rows(kRows);  // 2 GB, shared by both kernels
  std::vector<QueryMatch> out(kRows);
  for (auto _ : state) {
    classifier.classify(x.data(), kRows, out.data());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kRows));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * kRows * kDim * sizeof(float)));
  state.SetLabel(classifier.uses_avx2() ? "avx2+fma" : "eigen");
}
BENCHMARK(BM_QueryClassifyStream)->ArgsProduct({{0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

void BM_QueryClassifyResident(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(1));
  const QueryClassifier classifier(six_queries(), {.portable_kernel = state.range(0) == 1});
  const std::vector<float> chunk = random_rows(kChunkRows);  // 8 MB: stays in L3
  std::vector<QueryMatch> out(kRows);
  for (auto _ : state) {
    tbb::parallel_for(std::size_t{0}, kRows / kChunkRows, [&](std::size_t c) {
      classifier.classify(chunk.data(), kChunkRows, out.data() + c * kChunkRows);
    });
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * kRows));
  state.SetLabel(classifier.uses_avx2() ? "avx2+fma" : "eigen");
}
BENCHMARK(BM_QueryClassifyResident)->ArgsProduct({{0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(2.0);

}  // namespace
