// The fleet map on a real PostgreSQL 15 + PostGIS server the benchmark starts itself (the tests'
// harness, testing/postgres_server.hpp: a temporary cluster on a Unix socket, fsync off). A
// SIMULATED map of 16 submaps (40 x 40 voxels each, every voxel with a 256-d fp16 embedding: 13 MB
// of payload rows): push (MB/s and submaps/s) against plain COPY of the same rows (the reference:
// psql's \copy of the rows push wrote, exported by COPY TO, into tables of the same definition),
// pull of a 4-submap region, and a top-100 region query read through the summaries against the
// whole region pulled and searched. Figures: docs/fleet-design.md, "Measurements".
#include <benchmark/benchmark.h>

#include "bench_fleet_common.hpp"
#include "slamvdb/fleet/fleet_search.hpp"
#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::bench {
namespace {

constexpr int kFleetBenchSubmaps = 16, kFleetBenchSide = 40, kFleetBenchDim = 256;

// Submap s lies 20 m east of submap s - 1; its embeddings lie near axis s (plus noise), so a
// question about one axis has its answers in one submap.
const SemanticMap& fleet_bench_map() {
  static const SemanticMap map = [] {
    MapParams params;
    params.occupancy.voxel_size = 0.25;
    params.semantic = {kFleetBenchDim, EmbeddingPrecision::kFloat16};
    params.submap_length = 0;
    SemanticMap m(params, {.model_id = "fleet-bench-space", .source = "SIMULATED fleet benchmark patches"});
    uint64_t state = 0x9E3779B97F4A7C15ULL;
    std::vector<float> e(kFleetBenchDim);
    for (int s = 0; s < kFleetBenchSubmaps; ++s) {
      VoxelMap voxels(params);
      for (int x = 0; x < kFleetBenchSide; ++x)
        for (int y = 0; y < kFleetBenchSide; ++y) {
          for (float& v : e) {
            state ^= state << 13, state ^= state >> 7, state ^= state << 17;
            v = static_cast<float>(static_cast<int32_t>(state >> 32)) * (0.02f / 2147483648.0f);
          }
          e[static_cast<std::size_t>(s)] += 1.0f;
          voxels.occupancy().set_log_odds({x, y, 0}, 2.0f);
          voxels.semantics().set({x, y, 0}, e.data(), 1);
        }
      SubmapInfo info;
      info.id = s;
      info.T_world_submap.translation() = Vec3d(20.0 * s, 0, 0);
      info.path_length = 10;
      m.add_finished_submap(info, std::move(voxels));
    }
    return m;
  }();
  return map;
}

// The benchmark's database on the harness's server, with the map pushed once (for pull and query).
struct FleetBenchDatabase {
  testing::PostgresServer& server = testing::shared_postgres_server();
  std::string url;
  fleet::PushReport pushed;
  FleetBenchDatabase() {
    server.psql("DROP DATABASE IF EXISTS bench_fleet");
    server.psql("CREATE DATABASE bench_fleet");
    url = server.url("bench_fleet");
    pushed = fleet::FleetDatabase(url).push_map(fleet_bench_map(), {.session = "bench"});
  }
  void psql(const std::string& sql) const { server.psql(sql, "bench_fleet"); }
};
FleetBenchDatabase& fleet_bench_database() {
  static FleetBenchDatabase db;
  return db;
}

void BM_FleetPush(benchmark::State& state) {
  FleetBenchDatabase& db = fleet_bench_database();
  fleet::PushReport report;
  for (auto _ : state) {
    state.PauseTiming();
    db.psql("TRUNCATE slamvdb.sessions CASCADE");
    state.ResumeTiming();
    report = fleet::FleetDatabase(db.url).push_map(fleet_bench_map(), {.session = "bench"});
  }
  if (report.submaps_added != kFleetBenchSubmaps) state.SkipWithError("the push did not add every submap");
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * report.payload_bytes));
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * kFleetBenchSubmaps);
  state.counters["payload_MB"] = static_cast<double>(report.payload_bytes) / 1e6;
}

// The reference: the same rows loaded by plain COPY (bench_fleet_common.hpp).
void BM_FleetCopyReference(benchmark::State& state) {
  FleetBenchDatabase& db = fleet_bench_database();
  db.psql("TRUNCATE slamvdb.sessions CASCADE");
  fleet::FleetDatabase(db.url).push_map(fleet_bench_map(), {.session = "bench"});
  const FleetCopyReference reference(db.server, "bench_fleet");
  for (auto _ : state) {
    state.PauseTiming();
    reference.truncate();
    state.ResumeTiming();
    const testing::CommandResult r = reference.load();
    if (r.exit_code != 0) state.SkipWithError(r.output.c_str());
  }
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * db.pushed.payload_bytes));
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * kFleetBenchSubmaps);
}

fleet::PullRequest fleet_bench_region(double x_end) {
  return {Eigen::AlignedBox3d(Vec3d(-1, -1, -1), Vec3d(x_end, 11, 2))};
}

// A region of 4 submaps (x < 70 m) pulled and checked row by row (the map file's readers).
void BM_FleetPullRegion(benchmark::State& state) {
  FleetBenchDatabase& db = fleet_bench_database();
  fleet::PullReport report;
  for (auto _ : state) {
    fleet::FleetDatabase fleet(db.url);
    std::size_t voxels = 0;
    report = fleet.pull(fleet_bench_region(70), [&](fleet::PulledSubmap&& s) { voxels += s.voxels.semantics().size(); });
    benchmark::DoNotOptimize(voxels);
  }
  if (report.submaps != 4) state.SkipWithError("the region did not hold 4 submaps");
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * report.payload_bytes));
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * report.submaps));
}

// Top 100 near axis 0 over the whole fleet (16 submaps): arg 1 through the summaries
// (pull_for_search: one submap can answer), arg 0 the whole region pulled and searched.
void BM_FleetRegionTop100(benchmark::State& state) {
  FleetBenchDatabase& db = fleet_bench_database();
  Eigen::VectorXf q = Eigen::VectorXf::Zero(kFleetBenchDim);
  q[0] = 1.0f, q[1] = 0.05f;
  SearchOptions options;
  options.top_k = 100;
  const std::span<const float> query(q.data(), kFleetBenchDim);
  std::size_t read = 0;
  for (auto _ : state) {
    fleet::FleetDatabase fleet(db.url);
    if (state.range(0)) {
      const fleet::PrunedRegion pruned = pull_for_search(fleet, fleet_bench_region(400), query, options);
      benchmark::DoNotOptimize(similarity_search(pruned.map, query, options).size());
      read = pruned.report.submaps_scored;
    } else {
      const SemanticMap whole = fleet.pull_map(fleet_bench_region(400));
      benchmark::DoNotOptimize(similarity_search(whole, query, options).size());
      read = whole.num_submaps();
    }
  }
  state.counters["submaps_read"] = static_cast<double>(read);
}

BENCHMARK(BM_FleetPush)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);
BENCHMARK(BM_FleetCopyReference)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(5);
BENCHMARK(BM_FleetPullRegion)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_FleetRegionTop100)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace slamvdb::bench
