// The fleet map at scale (issue 24, "Scale out"): a sharded fleet on three real PostgreSQL 15 +
// PostGIS servers the benchmark starts (the tests' harness: the coordinator on the shared server,
// two shard servers joined by postgres_fdw, the README's procedure), N SIMULATED sessions pushed
// through FleetDatabase::push_map (what `slamvdb push` calls), then
// - push throughput (payload MB/s, submaps/s) against plain COPY of the same rows into the same
//   shard servers (bench_fleet_common.hpp);
// - a 100 m x 100 m region's top-100 query (pull_for_search + similarity_search, the path of
//   `query --db --bbox`): p50/p99 latency over distinct questions, which shards ran statements
//   (their statement logs), and the query worker's peak RSS growth (VmHWM after /proc/self/clear_refs).
// Args: N = 5 and 50 sessions. The site grows with N (each session starts 120 m further east);
// the region does not (it lies where sessions 0 and 1 overlap, whatever N), so its latency must
// stay flat. Figures: docs/fleet-design.md, "Measurements" (session 40).
//
// Reduced (SIMULATED) where it does not change what is measured: a submap is a flat 32 m x 12 m
// ground strip of 0.5 m voxels (1536 voxels, every one with a 64-d fp16 embedding: 0.2 MB of
// payload rows), 8 submaps per session 30 m apart. The fleet's work per submap (catalog look-ups,
// home tile, one transaction, COPY through the shard's foreign partition) and per region (tile
// look-up, GiST on footprints, the rows read) does not depend on what a voxel holds; only the
// bytes per submap do, and those are reported as MB/s beside submaps/s.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>

#include "bench_fleet_common.hpp"
#include "slamvdb/fleet/fleet_search.hpp"
#include "slamvdb/testing/postgres_shards.hpp"

namespace slamvdb::bench {
namespace {

constexpr int kScaleDim = 64, kScaleClasses = 16, kScaleSubmapsPerSession = 8;
constexpr int kScaleStripX = 64, kScaleStripY = 24;  // voxels of 0.5 m: 32 m x 12 m
constexpr double kScaleVoxel = 0.5, kScaleSessionStart = 120.0, kScaleSubmapStep = 30.0;
constexpr int kScaleQuestions = 100;
// 100 m x 100 m where sessions 0 and 1 overlap (x 120..242 m): the same map at every N.
const Eigen::AlignedBox3d kScaleRegion(Vec3d(140, -50, -10), Vec3d(240, 50, 10));

uint64_t scale_mix(uint64_t z) {  // splitmix64's finaliser
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Session i's drive: its world frame starts 120 m east of session i - 1's in the fleet frame
// (so each place is seen by two sessions and the site is 120 N + 120 m long); submap j is anchored
// 30 m further along a road that wiggles in y. A place's class comes from its 20 m square of the
// fleet frame, so overlapping sessions agree on what is where; each embedding is its class's axis,
// a session's own bias (sessions' encoders differ a little) and noise.
Pose scale_T_fleet_session(int session) {
  Pose T = Pose::Identity();
  T.translation() = Vec3d(kScaleSessionStart * session, 0, 0);
  return T;
}

SemanticMap scale_session_map(int session) {
  MapParams params;
  params.occupancy.voxel_size = kScaleVoxel;
  params.semantic = {kScaleDim, EmbeddingPrecision::kFloat16};
  params.submap_length = 0;
  SemanticMap map(params, {.model_id = "fleet-scale-space", .source = fmt::format("SIMULATED fleet scale drive {}", session)});
  uint64_t state = scale_mix(0x5CA1E + static_cast<uint64_t>(session));
  std::vector<float> e(kScaleDim);
  const Vec3d start = scale_T_fleet_session(session).translation();
  for (int j = 0; j < kScaleSubmapsPerSession; ++j) {
    SubmapInfo info;
    info.id = j;
    info.T_world_submap.translation() = Vec3d(kScaleSubmapStep * j, 12.0 * std::sin(0.7 * j + session), 0);
    info.time_range = {30.0 * j, 30.0 * j + 29};
    info.path_length = kScaleSubmapStep;
    VoxelMap voxels(params);
    for (int x = 0; x < kScaleStripX; ++x)
      for (int y = -kScaleStripY / 2; y < kScaleStripY / 2; ++y) {
        const Vec3d p = start + info.T_world_submap.translation() + kScaleVoxel * Vec3d(x + 0.5, y + 0.5, 0);
        const uint64_t place = scale_mix((static_cast<uint64_t>(std::floor(p.x() / 20)) << 32) ^
                                         static_cast<uint64_t>(std::floor(p.y() / 20) + 1000));
        for (float& v : e) {
          state ^= state << 13, state ^= state >> 7, state ^= state << 17;
          v = static_cast<float>(static_cast<int32_t>(state >> 32)) * (0.1f / 2147483648.0f);
        }
        e[place % kScaleClasses] += 1.0f;
        e[kScaleClasses + static_cast<std::size_t>(session) % (kScaleDim - kScaleClasses)] += 0.3f;
        voxels.occupancy().set_log_odds({x, y, 0}, 2.0f);
        voxels.semantics().set({x, y, 0}, e.data(), 1);
      }
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

// Question k (k < 100 all distinct): a class, a second class weighted less, a session's bias.
Eigen::VectorXf scale_question(int k) {
  Eigen::VectorXf q = Eigen::VectorXf::Zero(kScaleDim);
  q[k % kScaleClasses] = 1.0f;
  q[(k / kScaleClasses + 5 * k + 1) % kScaleClasses] += 0.2f + 0.05f * static_cast<float>(k % 7);
  q[kScaleClasses + k % (kScaleDim - kScaleClasses)] += 0.3f;
  return q;
}

testing::PostgresServerSet& scale_shard_servers() {
  static testing::PostgresServerSet servers(2, "scaleshard");
  return servers;
}

// A fleet of N sessions: the coordinator's database and one database on each shard server.
struct ScaleFleet {
  int sessions = 0;
  std::string coordinator, shard_db;  // database names (the same shard_db on both shard servers)
  fleet::PushReport pushed;            // summed over the sessions
  double push_seconds = 0, first_sessions_seconds = 0, last_sessions_seconds = 0;  // of 5 sessions each
  std::string url() const { return testing::shared_postgres_server().url(coordinator); }
};

void recreate_database(testing::PostgresServer& server, const std::string& name) {
  server.psql("DROP DATABASE IF EXISTS " + name);
  server.psql("CREATE DATABASE " + name);
}

// The README's procedure: shard a added to the empty coordinator, the first half of the sessions
// pushed (their tiles go to a), shard b added, the rest pushed (new tiles go to the newest shard:
// b). Only push_map is timed; each session's map is made before its push and dropped after.
ScaleFleet build_scale_fleet(int sessions) {
  ScaleFleet f;
  f.sessions = sessions;
  f.coordinator = fmt::format("bench_scale_{}", sessions);
  f.shard_db = f.coordinator + "_shard";
  recreate_database(testing::shared_postgres_server(), f.coordinator);
  for (int i = 0; i < 2; ++i) recreate_database(scale_shard_servers()[i], f.shard_db);
  fleet::FleetDatabase fleet(f.url());
  fleet.add_shard("a", scale_shard_servers()[0].url(f.shard_db));
  for (int s = 0; s < sessions; ++s) {
    if (s == (sessions + 1) / 2) fleet.add_shard("b", scale_shard_servers()[1].url(f.shard_db));
    const SemanticMap map = scale_session_map(s);
    const auto t0 = std::chrono::steady_clock::now();
    const fleet::PushReport r =
        fleet.push_map(map, {.session = fmt::format("drive{:03}", s), .T_fleet_session = scale_T_fleet_session(s)});
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (r.submaps_added != kScaleSubmapsPerSession) throw Error(fmt::format("session {}: not every submap was added", s));
    f.push_seconds += seconds;
    if (s < 5) f.first_sessions_seconds += seconds;
    if (s >= sessions - 5) f.last_sessions_seconds += seconds;
    f.pushed.submaps_added += r.submaps_added;
    f.pushed.rows_written += r.rows_written;
    f.pushed.payload_bytes += r.payload_bytes;
  }
  return f;
}

std::map<int, std::unique_ptr<ScaleFleet>>& scale_fleets() {
  static std::map<int, std::unique_ptr<ScaleFleet>> fleets;
  return fleets;
}
ScaleFleet& scale_fleet(int sessions) {
  std::unique_ptr<ScaleFleet>& f = scale_fleets()[sessions];
  if (!f) f = std::make_unique<ScaleFleet>(build_scale_fleet(sessions));
  return *f;
}

std::size_t shard_rows(int shard, const ScaleFleet& f, const std::string& table) {
  return std::stoul(testing::psql_value(scale_shard_servers()[shard], "SELECT count(*) FROM slamvdb." + table, f.shard_db));
}

void BM_FleetScalePush(benchmark::State& state) {
  const int sessions = static_cast<int>(state.range(0));
  for (auto _ : state) {
    scale_fleets().erase(sessions);
    const ScaleFleet& f = scale_fleet(sessions);
    state.SetIterationTime(f.push_seconds);
  }
  const ScaleFleet& f = scale_fleet(sessions);
  const double mb = static_cast<double>(f.pushed.payload_bytes) / 1e6;
  state.counters["payload_MB"] = mb;
  state.counters["submaps"] = f.pushed.submaps_added;
  state.counters["MB_per_s"] = mb / f.push_seconds;
  state.counters["submaps_per_s"] = f.pushed.submaps_added / f.push_seconds;
  // Does a push slow down as the fleet grows? The first five sessions' rate against the last five's.
  const double five = 5.0 * kScaleSubmapsPerSession;
  state.counters["first5_submaps_per_s"] = five / f.first_sessions_seconds;
  state.counters["last5_submaps_per_s"] = five / f.last_sessions_seconds;
  state.counters["shard_a_submaps"] = static_cast<double>(shard_rows(0, f, "submaps"));
  state.counters["shard_b_submaps"] = static_cast<double>(shard_rows(1, f, "submaps"));
}

// The same payload rows loaded by plain COPY into the same shard servers, one after the other.
void BM_FleetScaleCopyReference(benchmark::State& state) {
  const ScaleFleet& f = scale_fleet(static_cast<int>(state.range(0)));
  const FleetCopyReference references[2] = {{scale_shard_servers()[0], f.shard_db}, {scale_shard_servers()[1], f.shard_db}};
  double total = 0;
  for (auto _ : state) {
    double seconds = 0;
    for (const FleetCopyReference& reference : references) {
      reference.truncate();
      const auto t0 = std::chrono::steady_clock::now();
      const testing::CommandResult r = reference.load();
      seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (r.exit_code != 0) state.SkipWithError(r.output.c_str());
    }
    state.SetIterationTime(seconds);
    total += seconds;
  }
  // As the push's counters (MB of 10^6 bytes; Google Benchmark's bytes_per_second counts MiB).
  const double loads = static_cast<double>(state.iterations());
  state.counters["MB_per_s"] = loads * static_cast<double>(f.pushed.payload_bytes) / 1e6 / total;
  state.counters["submaps_per_s"] = loads * f.pushed.submaps_added / total;
}

// kB of the process from /proc/self/status ("VmRSS", "VmHWM").
double status_kb(const std::string& field) {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1));
  return 0;
}
// Resets VmHWM to the current RSS (Linux >= 4.0), so the peak of what follows can be read.
bool reset_peak_rss() {
  std::ofstream clear("/proc/self/clear_refs");
  return static_cast<bool>(clear << "5" << std::flush);
}

double percentile(std::vector<double> v, double p) {  // nearest rank
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(v.size())));
  return v[std::clamp<std::size_t>(rank, 1, v.size()) - 1];
}

// A query worker on one fleet: one connection held (as `serve --db` keeps idle ones), the
// region's top-100 for question k by the path of `query --db --bbox`.
struct ScaleQueryWorker {
  fleet::FleetDatabase fleet;
  SearchOptions options;
  fleet::PrunedSearchReport last;
  explicit ScaleQueryWorker(const ScaleFleet& f) : fleet(f.url()) {
    options.top_k = 100;
    options.region = QueryRegion{kScaleRegion, std::nullopt};
  }
  double ask(int k) {  // seconds
    const auto t0 = std::chrono::steady_clock::now();
    const Eigen::VectorXf q = scale_question(k);
    const std::span<const float> query(q.data(), kScaleDim);
    const fleet::PrunedRegion pruned = pull_for_search(fleet, {kScaleRegion}, query, options);
    benchmark::DoNotOptimize(similarity_search(pruned.map, query, options).size());
    last = pruned.report;
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
};

// The peak RSS growth (MB) of a new worker on `f` over its connection and `questions` questions;
// -1 when VmHWM cannot be reset.
double worker_peak_growth_mb(const ScaleFleet& f, int questions) {
  ::malloc_trim(0);  // memory freed before goes back to the system: reusing it counts as growth
  if (!reset_peak_rss()) return -1;
  const double before_kb = status_kb("VmRSS");
  {
    ScaleQueryWorker worker(f);
    for (int k = 0; k < questions; ++k) worker.ask(k);
  }
  return (status_kb("VmHWM") - before_kb) / 1024.0;
}

// Args: the small and the large fleet. The latency of each is measured question by question in
// turns (small then large, then large then small, ...), so the load of a shared machine falls on
// both alike; the memory of a worker on each alone. Which shards ran statements: each shard
// server's log, counted by database (each fleet has its own database on both shard servers).
void BM_FleetScaleRegionQuery(benchmark::State& state) {
  const ScaleFleet* fleets[2] = {&scale_fleet(static_cast<int>(state.range(0))), &scale_fleet(static_cast<int>(state.range(1)))};
  const auto statements = [&](int shard, int fleet) {
    return static_cast<double>(testing::statements_in(scale_shard_servers()[shard], fleets[fleet]->shard_db));
  };
  for (int i = 0; i < 2; ++i) testing::log_statements(scale_shard_servers()[i], true);
  double before[2][2];
  for (int shard = 0; shard < 2; ++shard)
    for (int fleet = 0; fleet < 2; ++fleet) before[shard][fleet] = statements(shard, fleet);
  std::vector<double> latencies[2];
  std::size_t in_region[2] = {0, 0}, read[2] = {0, 0};
  for (auto _ : state) {
    ScaleQueryWorker workers[2] = {ScaleQueryWorker(*fleets[0]), ScaleQueryWorker(*fleets[1])};
    for (ScaleQueryWorker& w : workers) w.ask(kScaleQuestions);  // untimed: opens the shards' connections
    double total = 0;
    for (int k = 0; k < kScaleQuestions; ++k)
      for (int turn = 0; turn < 2; ++turn) {
        const int fleet = (k + turn) % 2;
        latencies[fleet].push_back(workers[fleet].ask(k));
        total += latencies[fleet].back();
      }
    for (int fleet = 0; fleet < 2; ++fleet)
      in_region[fleet] = workers[fleet].last.submaps_in_region, read[fleet] = workers[fleet].last.submaps_scored;
    state.SetIterationTime(total);
  }
  for (int fleet = 0; fleet < 2; ++fleet) {
    const std::string n = std::to_string(fleets[fleet]->sessions);
    state.counters["p50_ms_" + n] = percentile(latencies[fleet], 0.5) * 1e3;
    state.counters["p99_ms_" + n] = percentile(latencies[fleet], 0.99) * 1e3;
    state.counters["region_submaps_" + n] = static_cast<double>(in_region[fleet]);
    state.counters["read_" + n] = static_cast<double>(read[fleet]);
    state.counters["shard_a_statements_" + n] = statements(0, fleet) - before[0][fleet];
    state.counters["shard_b_statements_" + n] = statements(1, fleet) - before[1][fleet];
  }
  for (int i = 0; i < 2; ++i) testing::log_statements(scale_shard_servers()[i], false);
  // What makes the comparison hold: the same region map in both fleets, asked of shard a only.
  if (in_region[0] != in_region[1] || in_region[0] == 0) state.SkipWithError("the region differs between the fleets");
  if (state.counters["shard_b_statements_" + std::to_string(fleets[0]->sessions)] > 0 ||
      state.counters["shard_b_statements_" + std::to_string(fleets[1]->sessions)] > 0)
    state.SkipWithError("the region, all on shard a, asked shard b");
  state.counters["p50_ratio"] = percentile(latencies[1], 0.5) / percentile(latencies[0], 0.5);
  state.counters["p99_ratio"] = percentile(latencies[1], 0.99) / percentile(latencies[0], 0.99);
  for (int fleet = 0; fleet < 2; ++fleet)
    state.counters["worker_peak_growth_MB_" + std::to_string(fleets[fleet]->sessions)] =
        worker_peak_growth_mb(*fleets[fleet], 10);
  state.counters["process_rss_MB"] = status_kb("VmRSS") / 1024.0;
}

BENCHMARK(BM_FleetScalePush)->Arg(5)->Arg(50)->Iterations(1)->Repetitions(3)->ReportAggregatesOnly(true)
    ->UseManualTime()->Unit(benchmark::kSecond);
BENCHMARK(BM_FleetScaleCopyReference)->Arg(5)->Arg(50)->Iterations(3)->UseManualTime()->Unit(benchmark::kSecond);
BENCHMARK(BM_FleetScaleRegionQuery)->Args({5, 50})->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
}  // namespace slamvdb::bench
