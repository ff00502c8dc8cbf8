// `slamvdb serve` on a million semantic voxels (bench_maps.hpp's road map, 1.06 M cells of 512-d
// fp16, built in process): the answers of POST /api/query (top 100, JSON encoded) and POST /api/at
// without HTTP, and a bounded load over loopback: a real MapServer on 127.0.0.1, N client threads,
// a fixed count of requests each, every query a distinct vector (no cache can help), latencies
// reported as p50 / p99 (counters, ms). Figures: docs/serve-design.md, "Measurements".
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <mutex>
#include <thread>

#include "bench_maps.hpp"
#include "slamvdb/server/http_server.hpp"
#include "slamvdb/server/httplib_include.hpp"

namespace slamvdb::bench {
namespace {

// The map served with its ANN index (built once, as `serve` builds it at start; requests with
// "exact": true scan every cell).
const std::shared_ptr<const SemanticMapService>& serve_bench_service() {
  static const std::shared_ptr<const SemanticMapService> service = std::make_shared<SemanticMapService>(
      std::shared_ptr<const SemanticMap>(&indexed_map(), [](const SemanticMap*) {}),
      nlohmann::json{{"submaps", nlohmann::json::array()}}, std::make_unique<AnnIndex>(indexed_map()));
  return service;
}

// Question i: near one submap's prototype (e[i % 13]) with a small twist of its own, so that no
// two questions are the same vector.
Eigen::VectorXf serve_bench_query(int i) {
  Eigen::VectorXf q = Eigen::VectorXf::Zero(512);
  q[i % kSubmaps] = 1.0f;
  q[13 + i % 499] += 0.05f + 0.001f * static_cast<float>(i / 499);
  return q;
}

QueryRequest serve_bench_request(int i, bool exact) {
  QueryRequest r;
  r.terms.vectors = {serve_bench_query(i)};
  r.search.top_k = 100;
  r.exact = exact;
  return r;
}

// Points spread over the road (x along it, y across), a third of them off the surface.
std::vector<Vec3d> serve_bench_points(std::size_t n) {
  std::vector<Vec3d> points(n);
  const double length = kSubmaps * 316 * 0.25 * 0.8 + 316 * 0.25 * 0.2, width = 316 * 0.25;
  for (std::size_t i = 0; i < n; ++i)
    points[i] = {length * static_cast<double>((i * 7919) % n) / static_cast<double>(n),
                 width * static_cast<double>((i * 104729) % 997) / 997.0, (i % 3 == 0) ? 5.0 : 0.1};
  return points;
}

// Arg: 1 for "exact": true (every cell scored), 0 through the ANN index.
void BM_ServeQueryAnswer(benchmark::State& state) {
  AnswerContext context;
  context.map = serve_bench_service().get();
  int i = 0;
  std::size_t bytes = 0;
  for (auto _ : state) bytes = answer_query(context, serve_bench_request(i++, state.range(0) == 1)).dump().size();
  state.counters["cells"] = static_cast<double>(context.map->semantic_cells());
  state.counters["answer_bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_ServeQueryAnswer)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->UseRealTime();

// The ANN index on the bench map: build time, memory, the share of cells scored per question and
// recall@100 against exact scoring over 52 questions (four per submap prototype). Arg: lists
// probed (0: the index's default).
void BM_ServeAnnRecall(benchmark::State& state) {
  const std::shared_ptr<const AnnIndex> index = serve_bench_service()->ann();
  const AnnIndex& ann = *index;
  double recall = 0, scored = 0;
  constexpr int kQuestions = 52;
  for (auto _ : state) {
    recall = scored = 0;
    for (int i = 0; i < kQuestions; ++i) {
      const Eigen::VectorXf q = serve_bench_query(i * 37);
      SearchOptions exact;
      exact.top_k = 100;
      SearchOptions approximate = exact;
      approximate.ann = &ann;
      approximate.ann_probes = static_cast<std::size_t>(state.range(0));
      const auto truth = similarity_search(indexed_map(), {q.data(), 512}, exact);
      const auto found = similarity_search(indexed_map(), {q.data(), 512}, approximate);
      std::vector<IndexCellKey> true_cells;
      for (const ScoredCell& c : truth) true_cells.push_back(c.cell);
      std::sort(true_cells.begin(), true_cells.end());
      for (const ScoredCell& c : found) recall += std::binary_search(true_cells.begin(), true_cells.end(), c.cell) ? 0.01 : 0;
      const Eigen::VectorXf unit = q.normalized();
      std::size_t codes_scored = 0;
      ann.candidates({unit.data(), 512}, approximate.ann_probes, 100, &codes_scored);
      scored += static_cast<double>(codes_scored);
    }
  }
  const AnnIndexStats stats = ann.stats();
  state.counters["recall_at_100"] = recall / kQuestions;
  state.counters["share_scored"] = scored / kQuestions / static_cast<double>(stats.cells);
  state.counters["build_s"] = stats.build_seconds;
  state.counters["training_s"] = stats.training_seconds;
  state.counters["memory_MB"] = static_cast<double>(stats.memory_bytes) / 1e6;
  state.counters["lists"] = static_cast<double>(stats.lists);
  state.counters["probes"] = state.range(0) ? static_cast<double>(state.range(0)) : static_cast<double>(stats.probes);
}
BENCHMARK(BM_ServeAnnRecall)->Arg(0)->Arg(16)->Arg(24)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

// Arg: points per request.
void BM_ServeAtAnswer(benchmark::State& state) {
  AnswerContext context;
  context.map = serve_bench_service().get();
  AtRequest request;
  request.points = serve_bench_points(static_cast<std::size_t>(state.range(0)));
  std::size_t found = 0;
  for (auto _ : state) found = nlohmann::json::parse(answer_at(context, request)).at("found").get<std::size_t>();
  state.counters["found"] = static_cast<double>(found);
  state.counters["points_per_s"] =
      benchmark::Counter(static_cast<double>(state.range(0)), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_ServeAtAnswer)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->UseRealTime();

// POST /api/at's whole work in the server but the socket, 100 000 points a request (issue 21's
// target: 100 000 points per second), by stage. Arg: 0 the look-ups alone (the map service's `at`),
// 1 + the answer's JSON text, 2 + decoding the request body (what a request costs but the socket).
void BM_ServeAtStages(benchmark::State& state) {
  constexpr std::size_t kPoints = 100000;
  AnswerContext context;
  context.map = serve_bench_service().get();
  const std::vector<Vec3d> points = serve_bench_points(kPoints);
  nlohmann::json body = nlohmann::json::array();
  for (const Vec3d& p : points) body.push_back({p.x(), p.y(), p.z()});
  const std::string text = nlohmann::json({{"points", body}}).dump();
  ServerLimits limits;
  limits.max_points = kPoints;
  AtRequest request;
  request.points = points;
  const int stage = static_cast<int>(state.range(0));
  std::size_t bytes = 0;
  for (auto _ : state) {
    if (stage == 0) {
      bytes = context.map->at(points, nullptr, context.classify, context.model_check, false).size();
    } else if (stage == 1) {
      bytes = answer_at(context, request).size();
    } else {
      bytes = answer_at(context, decode_at_request(text, limits)).size();
    }
    benchmark::DoNotOptimize(bytes);
  }
  state.counters["answer_bytes"] = static_cast<double>(bytes);
  state.counters["points_per_s"] = benchmark::Counter(static_cast<double>(kPoints), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_ServeAtStages)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

// Args: clients, requests per client, route (0: POST /api/query top 100, distinct vectors, through
// the ANN index; 1: POST /api/at with 10 000 points; 2: as 0 with "exact": true), queries computed
// at once (--compute-slots: 0 the default, one per hardware thread; = clients: no waiting, every
// admitted answer computes at once, as before s40). One iteration: the whole load, bounded in count.
void BM_ServeLoad(benchmark::State& state) {
  const int clients = static_cast<int>(state.range(0)), per_client = static_cast<int>(state.range(1));
  const bool at = state.range(2) == 1, exact = state.range(2) == 2;
  ServerOptions options;
  options.port = 0;
  options.limits.max_concurrent = static_cast<std::size_t>(clients);
  options.limits.compute_slots = static_cast<std::size_t>(state.range(3));
  options.limits.max_body_bytes = 16 << 20;
  options.limits.rate_per_client = 0;  // every client is 127.0.0.1 here
  options.model_check = ModelIdCheck::kIgnore;
  MapServer server(serve_bench_service(), nullptr, std::nullopt, options);
  const int port = server.bind();
  std::thread serving([&server] { server.run(); });
  // The bodies, made before the clock starts.
  std::vector<std::string> bodies;
  if (at) {
    nlohmann::json points = nlohmann::json::array();
    for (const Vec3d& p : serve_bench_points(10000)) points.push_back({p.x(), p.y(), p.z()});
    bodies.push_back(nlohmann::json({{"points", points}}).dump());
  } else {
    for (int i = 0; i < clients * per_client; ++i) {
      const Eigen::VectorXf q = serve_bench_query(i);
      bodies.push_back(nlohmann::json({{"vector", std::vector<float>(q.data(), q.data() + q.size())}, {"top_k", 100}, {"exact", exact}}).dump());
    }
  }
  std::vector<double> latencies_ms;
  std::size_t errors = 0;
  double seconds = 0;
  for (auto _ : state) {
    latencies_ms.clear();
    errors = 0;
    std::mutex m;
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::thread> threads;
    for (int c = 0; c < clients; ++c)
      threads.emplace_back([&, c] {
        httplib::Client client("127.0.0.1", port);
        client.set_read_timeout(120, 0);
        for (int r = 0; r < per_client; ++r) {
          const std::string& body = bodies[at ? 0 : static_cast<std::size_t>(c * per_client + r)];
          const auto t0 = std::chrono::steady_clock::now();
          const auto res = client.Post(at ? "/api/at" : "/api/query", body, "application/json");
          const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
          const std::lock_guard lock(m);
          latencies_ms.push_back(ms);
          if (!res || res->status != 200) ++errors;
        }
      });
    for (std::thread& t : threads) t.join();
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  server.stop();
  serving.join();
  std::sort(latencies_ms.begin(), latencies_ms.end());
  const auto quantile = [&](double q) {
    return latencies_ms.empty() ? 0.0 : latencies_ms[std::min(latencies_ms.size() - 1, static_cast<std::size_t>(q * latencies_ms.size()))];
  };
  state.counters["requests"] = static_cast<double>(latencies_ms.size());
  state.counters["errors"] = static_cast<double>(errors);
  state.counters["p50_ms"] = quantile(0.50);
  state.counters["p99_ms"] = quantile(0.99);
  state.counters["max_ms"] = latencies_ms.empty() ? 0.0 : latencies_ms.back();
  state.counters["requests_per_s"] = static_cast<double>(latencies_ms.size()) / seconds;
  if (at) state.counters["points_per_s"] = 10000.0 * static_cast<double>(latencies_ms.size()) / seconds;
}
BENCHMARK(BM_ServeLoad)
    ->Args({1, 16, 0, 0})
    ->Args({32, 4, 0, 0})
    ->Args({32, 16, 0, 0})
    ->Args({32, 4, 0, 32})
    ->Args({32, 16, 0, 32})
    ->Args({32, 4, 2, 0})
    ->Args({8, 4, 1, 0})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace slamvdb::bench
