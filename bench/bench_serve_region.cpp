// A region question (POST /api/query "region": a 100 m x 100 m box, top 100, exact) on the road
// map of bench_maps.hpp and on the same road ten times longer (issue 21, "Speed": the same latency
// on a map ten times larger, because submaps whose bounds miss the box are not read). The box is
// at the same place on both roads, so both answers score the same cells. Embeddings are 64-d fp16
// here so that the long road (130 submaps, 10.4 M cells) fits in memory beside other work: the
// 512-d road of bench_serve.cpp is 1.4 GB, ten times that is not available; the comparison is
// between the two lengths at one dimension. Figures: docs/serve-design.md, "Measurements".
#include <benchmark/benchmark.h>

#include <map>

#include "bench_maps.hpp"
#include "slamvdb/server/map_answers.hpp"

namespace slamvdb::bench {
namespace {

constexpr int kRegionDim = 64;

// Roads of `submaps` submaps (13: the base; 130: ten times longer), built once each.
const SemanticMapService& road_service(int submaps) {
  static std::map<int, std::unique_ptr<SemanticMapService>> services;
  auto& s = services[submaps];
  if (!s)
    s = std::make_unique<SemanticMapService>(std::shared_ptr<const SemanticMap>(make_indexed_map(submaps, 0.2, kRegionDim, false)),
                                             nlohmann::json{{"submaps", nlohmann::json::array()}});
  return *s;
}

// A 100 m x 100 m box over the road from x = 300 m (past the first submaps of both roads).
QueryRegion region_box() {
  QueryRegion r;
  r.box = Eigen::AlignedBox3d(Vec3d(300, -10, -10), Vec3d(400, 90, 10));
  return r;
}

// Arg: submaps of the road. Questions are distinct vectors near one submap's prototype.
void BM_ServeRegionQuery(benchmark::State& state) {
  const SemanticMapService& service = road_service(static_cast<int>(state.range(0)));
  AnswerContext context;
  context.map = &service;
  int i = 0;
  std::size_t count = 0;
  for (auto _ : state) {
    QueryRequest r;
    Eigen::VectorXf q = Eigen::VectorXf::Zero(kRegionDim);
    q[i % kRegionDim] = 1.0f;
    q[(i + 7) % kRegionDim] += 0.05f + 0.001f * static_cast<float>(i / kRegionDim);
    ++i;
    r.terms.vectors = {q};
    r.search.top_k = 100;
    r.search.region = region_box();
    r.exact = true;
    count = answer_query(context, r).at("count").get<std::size_t>();
  }
  state.counters["map_cells"] = static_cast<double>(service.semantic_cells());
  state.counters["region_cells"] = static_cast<double>(service.region_cells(region_box()));
  state.counters["answered"] = static_cast<double>(count);
}
BENCHMARK(BM_ServeRegionQuery)->Arg(13)->Arg(130)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

}  // namespace
}  // namespace slamvdb::bench
