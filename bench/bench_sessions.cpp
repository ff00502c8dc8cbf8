// Issue 23's speed targets on two 3 km SIMULATED maps (testing/simulated_sessions.hpp: surface
// samples of a procedural terrain along a winding route, 50 m submaps of the occupied 0.25 m
// voxels within 35 m, 60 submaps per map): aligning them (target: under 30 s on 2 cores), and
// merging them (load both files, merge, write the site map) against just reading the two files,
// in MB/s of the input files (target: merging bounded by I/O).
// The other map is the same terrain cut into submaps 25 m later; for the alignment it is seen
// in another world frame (turned 37 degrees, moved), for the merge in the base's (as `align`
// leaves it).
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <filesystem>

#include "slamvdb/sessions/map_merge.hpp"
#include "slamvdb/sessions/session_alignment.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/simulated_sessions.hpp"

namespace slamvdb::bench {
namespace {

namespace fs = std::filesystem;
using slamvdb::testing::AlignTestWorld;

constexpr int kSessionsRoute = 3000;       // metres: 60 submaps of 50 m
constexpr int kSessionsOtherStart = 25;    // the other map's submaps start half a submap later
constexpr int kSessionsSemanticDim = 16;   // the merge maps' embeddings (fp16), one per occupied voxel

struct ThreeKmSessions {
  AlignTestWorld world;
  Pose T_other_world = testing::make_align_test_pose(37.0, Vec3d(40.0, -25.0, 1.35));
  std::vector<sessions::SessionSubmap> base, other;
};

const ThreeKmSessions& three_km_sessions() {
  static const ThreeKmSessions s = [] {
    ThreeKmSessions out;
    out.world = testing::make_align_world(7, kSessionsRoute + kSessionsOtherStart);
    out.base = testing::make_align_session(out.world, Pose::Identity(), 0, kSessionsRoute);
    out.other = testing::make_align_session(out.world, out.T_other_world, kSessionsOtherStart,
                                            kSessionsRoute + kSessionsOtherStart);
    return out;
  }();
  return s;
}

// Aligns the two sessions (Args: threads, AlignmentConfig::survey_places: 48 the default, 0 every
// candidate verified from its descriptor). Counters: places, verified and consistent pairs, and
// the error at the route's middle (metres).
void BM_AlignSessions3km(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(state.range(0)));
  const ThreeKmSessions& s = three_km_sessions();
  sessions::AlignmentConfig config;
  config.survey_places = static_cast<std::size_t>(state.range(1));
  sessions::SessionAlignment r;
  for (auto _ : state) {
    r = sessions::align_sessions(s.base, s.other, config);
    benchmark::DoNotOptimize(r);
  }
  if (!r.aligned) {
    state.SkipWithError(("refused: " + r.refused).c_str());
    return;
  }
  const Vec3d mid = s.T_other_world * s.world.route[s.world.route.size() / 2];
  state.counters["submaps"] = static_cast<double>(s.other.size());
  state.counters["places"] = static_cast<double>(r.other_places);
  state.counters["candidates"] = static_cast<double>(r.candidate_pairs);
  state.counters["verified"] = static_cast<double>(r.verified.size());
  state.counters["surveyed"] = static_cast<double>(r.surveyed_places);
  state.counters["guided"] = static_cast<double>(r.guided_pairs);
  state.counters["consistent"] = static_cast<double>(r.consistent.size());
  state.counters["error_m"] = (r.T_base_other * mid - s.T_other_world.inverse() * mid).norm();
  state.SetLabel(fmt::format("SIMULATED, {} + {} submaps", s.base.size(), s.other.size()));
}
BENCHMARK(BM_AlignSessions3km)
    ->Args({1, 48})
    ->Args({2, 48})
    ->Args({2, 0})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

// A session as a map with semantics: every occupied voxel also holds an embedding (count 1-4).
SemanticMap semantic_session_map(const std::vector<sessions::SessionSubmap>& submaps, const std::string& source) {
  MapParams params;
  params.occupancy.voxel_size = testing::kAlignTestVoxel;
  params.semantic = {kSessionsSemanticDim, EmbeddingPrecision::kFloat16};
  SemanticMap map(params, MapInfo{.source = source});
  std::vector<float> e(kSessionsSemanticDim);
  for (const sessions::SessionSubmap& s : submaps) {
    VoxelMap voxels(params);
    uint32_t n = 0;
    for (const Vec3f& p : s.occupied_submap) {
      const VoxelKey k = voxels.occupancy().key_of(p.cast<double>());
      voxels.occupancy().set_log_odds(k, params.occupancy.clamp_max);
      for (int d = 0; d < kSessionsSemanticDim; ++d) e[d] = static_cast<float>((k.x() + 3 * k.y() + 7 * d) % 11) - 5.f;
      voxels.semantics().set(k, e.data(), 1 + n++ % 4);
    }
    SubmapInfo info;
    info.id = s.id;
    info.T_world_submap = s.T_world_submap;
    info.finished = true;
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

fs::path sessions_bench_dir;  // removed at exit

// The two map files in one world (the other as `align` leaves it), written once per run.
struct MergeFiles {
  fs::path dir, base, other;
  double megabytes = 0;
};
const MergeFiles& merge_files() {
  static const MergeFiles f = [] {
    MergeFiles out;
    out.dir = fs::temp_directory_path() / ("slamvdb_bench_sessions_" + std::to_string(::getpid()));
    fs::create_directories(out.dir);
    sessions_bench_dir = out.dir;
    std::atexit([] { fs::remove_all(sessions_bench_dir); });
    out.base = out.dir / "base.svdb";
    out.other = out.dir / "other.svdb";
    const ThreeKmSessions& s = three_km_sessions();
    save_map(out.base, semantic_session_map(s.base, "SIMULATED 3 km, session A"));
    save_map(out.other, semantic_session_map(testing::make_align_session(s.world, Pose::Identity(), kSessionsOtherStart,
                                                                         kSessionsRoute + kSessionsOtherStart),
                                             "SIMULATED 3 km, session B"));
    out.megabytes = static_cast<double>(fs::file_size(out.base) + fs::file_size(out.other)) / 1e6;
    return out;
  }();
  return f;
}

void report_rate(benchmark::State& state, double megabytes) {
  state.counters["input_MB"] = megabytes;
  state.counters["MB/s"] = benchmark::Counter(megabytes * static_cast<double>(state.iterations()),
                                              benchmark::Counter::kIsRate);
}

// Reading the two files (load_map: every submap's voxels in memory): the I/O bound.
void BM_ReadTwoSessionMaps(benchmark::State& state) {
  const MergeFiles& f = merge_files();
  for (auto _ : state) {
    SemanticMap a = load_map(f.base), b = load_map(f.other);
    benchmark::DoNotOptimize(a.num_occupied_voxels() + b.num_occupied_voxels());
  }
  report_rate(state, f.megabytes);
}
BENCHMARK(BM_ReadTwoSessionMaps)->Unit(benchmark::kSecond)->Iterations(2)->UseRealTime();

// What `slamvdb merge` does: read both, merge (overlapping submaps of the two sessions folded
// together), write the site map.
void BM_MergeTwoSessionMaps(benchmark::State& state) {
  const MergeFiles& f = merge_files();
  const fs::path site = f.dir / "site.svdb";
  std::size_t merges = 0;
  for (auto _ : state) {
    std::vector<SemanticMap> inputs;
    inputs.push_back(load_map(f.base));
    inputs.push_back(load_map(f.other));
    sessions::MapMergeReport report;
    const SemanticMap merged = sessions::merge_session_maps(inputs, {"a", "b"}, report);
    save_map(site, merged);
    merges = report.absorbed.size();
  }
  report_rate(state, f.megabytes);
  state.counters["merges"] = static_cast<double>(merges);
  state.counters["site_MB"] = static_cast<double>(fs::file_size(site)) / 1e6;
}
BENCHMARK(BM_MergeTwoSessionMaps)->Unit(benchmark::kSecond)->Iterations(2)->UseRealTime();

}  // namespace
}  // namespace slamvdb::bench
