// Crash-safe checkpoints: the map file grows submap by submap while mapping; submaps may leave
// memory and come back; a run killed at any moment leaves a file that loads, and --resume
// continues it to the map an uninterrupted run gives.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/store/map_file_writer.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using testing::run_cli;
using testing::shell_quote;

MapInfo map_info(const std::string& model_id) {
  MapInfo info;
  info.model_id = model_id;
  return info;
}

class Checkpoints : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("slamvdb_checkpoints_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    synth::SynthConfig config;
    config.seed = 5;
    config.length_m = 120.0;
    config.image_width = 160;
    config.image_height = 100;
    // A quarter of the OS1's columns: what is checked here (which submaps reach the file, what a
    // kill leaves, what resume adds) does not depend on the scans' density, and every test below
    // maps the 240 scans several times. The sanitizer run drives the same loop twice as fast
    // (120 scans): the same 10 m submaps, the same loop back to the start (slamvdb/testing/test_scale.hpp).
    config.speed_mps = testing::test_size(5.0, 10.0);
    config.lidar.columns = 256;
    synth::write_synthetic_sequence(config, sequence(), true);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static fs::path sequence() { return dir_ / "seq"; }
  static fs::path file(const std::string& name) { return dir_ / name; }
  static PipelineOptions options() {
    PipelineOptions o;
    o.map.semantic.dim = 16;
    o.map.submap_length = 10.0;
    return o;
  }
  static std::string map_command(const fs::path& out) {
    return fmt::format("map {} -o {} --dim 16 --feature-size 64x40 --submap-length 10 --quiet",
                       shell_quote(sequence().string()), shell_quote(out.string()));
  }
  static std::unique_ptr<FeatureSource> features() {
    SimulatedEncoderConfig c = SimulatedEncoderConfig::clean();  // the mapping mechanics, not the failure modes
    c.dim = 16, c.width = 64, c.height = 40;
    return std::make_unique<EncoderFeatureSource>(std::make_unique<SimulatedDenseEncoder>(c),
                                                  EncoderFeatureSource::Input::kLabels);
  }
  static inline fs::path dir_;
};

// Written submap by submap, the file loads to the map the run returns; letting far submaps leave
// memory (and reading them back) changes nothing in the file.
TEST_F(Checkpoints, TheGrowingFileIsTheMapAndFarSubmapsMayLeaveMemory) {
  const Sequence seq = read_sequence(sequence());
  auto source = features();
  PipelineOptions o = options();
  auto writer = MapFileWriter::create(file("grown.svdb"), o.map, map_info(source->model_id()));
  o.store = writer.get();
  PipelineReport report;
  const SemanticMap map = build_map(seq, source.get(), o, report);
  writer->finish(map.info(), map.memory_bytes());
  ASSERT_GE(map.num_submaps(), 8u);
  const SemanticMap grown = load_map(file("grown.svdb"));
  EXPECT_EQ(grown.num_submaps(), map.num_submaps());
  testing::expect_same_index_cells(grown, map);

  auto unload_writer = MapFileWriter::create(file("unloaded.svdb"), o.map, map_info(source->model_id()));
  o.store = unload_writer.get();
  o.unload_radius = 25.0;
  PipelineReport unload_report;
  const SemanticMap in_memory = build_map(seq, source.get(), o, unload_report);
  unload_writer->finish(in_memory.info(), in_memory.memory_bytes());
  EXPECT_GT(unload_report.submaps_unloaded, 3u);
  EXPECT_GT(unload_report.submaps_reloaded, 0u);  // the drive is a loop: its start comes near again
  EXPECT_LT(in_memory.num_submaps(), map.num_submaps());
  EXPECT_EQ(unload_report.submaps, map.num_submaps());
  testing::expect_same_index_cells(load_map(file("unloaded.svdb")), map);
}

// A correction of a submap that has left memory reaches the file without reading the submap back
// (a loop closer moves every submap at every loop), and the submap comes back at its new anchor.
TEST_F(Checkpoints, CorrectionsReachSubmapsThatLeftMemory) {
  const Sequence seq = read_sequence(sequence());
  PipelineOptions o = options();
  auto writer = MapFileWriter::create(file("corrected.svdb"), o.map, MapInfo{});
  MapperOptions m;
  m.map = o.map;
  m.unload_radius = 15.0;
  Mapper mapper(m, SemanticMap(o.map), nullptr, writer.get());
  for (std::size_t i = 0; i < seq.poses.size(); ++i) mapper.add_pose(seq.poses.stamps()[i], seq.poses.poses()[i]);
  for (std::size_t i = 0; i < seq.scans.size() / 2; ++i) mapper.add_scan(seq.scans[i].stamp, read_scan(seq.scans[i]).points);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (mapper.report().scans_integrated < seq.scans.size() / 2 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_FALSE(mapper.map().submap_info(0)) << "submap 0 should have left memory";
  const SubmapInfo before = writer->load(0).first;
  Pose moved = before.T_world_submap;
  moved.translation() += Vec3d(0.5, -0.25, 0.0);
  mapper.correct_submaps({{0, moved}});
  EXPECT_FALSE(mapper.map().submap_info(0));  // moved where it waits, not read back
  const std::vector<SubmapInfo> all = mapper.submaps();  // in memory or not
  ASSERT_GE(all.size(), 2u);
  EXPECT_EQ(all.front().id, 0);
  EXPECT_TRUE(all.front().T_world_submap.isApprox(moved, 1e-12));
  Pose sheared = moved;
  sheared.matrix()(0, 1) = 0.5;  // not rigid: refused, nothing moves
  EXPECT_THROW(mapper.correct_submaps({{0, sheared}, {all.back().id, all.back().T_world_submap}}), Error);
  mapper.end_mapping();
  mapper.merge_submaps(0, 1);  // merged or refused, both are read back first
  ASSERT_TRUE(mapper.map().submap_info(0));
  EXPECT_TRUE(mapper.map().submap_info(0)->T_world_submap.isApprox(moved, 1e-12));
  mapper.finish();
  const SemanticMap saved = load_map(file("corrected.svdb"));
  ASSERT_TRUE(saved.submap_info(0));
  EXPECT_TRUE(saved.submap_info(0)->T_world_submap.isApprox(moved, 1e-12));
}


std::size_t submaps_in(const fs::path& path) {
  try {
    return read_map_summary(path).submaps.size();
  } catch (const Error&) {
    return 0;  // not created yet
  }
}

// kill -9 at several moments (after the first submap, in the middle of a commit, near the end):
// every file left loads and holds every submap committed before the kill, equal to the same
// submap of an uninterrupted run; --resume then gives the uninterrupted run's map.
TEST_F(Checkpoints, KilledRunsLeaveLoadableFilesAndResumeGivesTheUninterruptedMap) {
  const auto full_run = run_cli(map_command(file("full.svdb")), 300);
  ASSERT_EQ(full_run.exit_code, 0) << full_run.output;
  const SemanticMap full = load_map(file("full.svdb"));
  const std::size_t n = full.num_submaps();
  ASSERT_GE(n, 8u);

  enum class Moment { kAfterFirstSubmap, kInsideACommit, kNearTheEnd };
  for (const Moment moment : {Moment::kAfterFirstSubmap, Moment::kInsideACommit, Moment::kNearTheEnd}) {
    const fs::path out = file(fmt::format("killed{}.svdb", static_cast<int>(moment)));
    const fs::path journal = out.string() + "-journal";
    testing::ChildProcess child(std::string(SLAMVDB_CLI_PATH) + " " + map_command(out), file("child.log"));
    ASSERT_TRUE(child.started());
    std::size_t seen = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    while (child.running() && std::chrono::steady_clock::now() < deadline) {
      if (moment == Moment::kInsideACommit && seen >= 2 && fs::exists(journal)) break;
      seen = submaps_in(out);
      if (moment == Moment::kAfterFirstSubmap && seen >= 1) break;
      if (moment == Moment::kNearTheEnd && seen >= n - 2) break;
      // Not a busy loop: a spinning core slowed the child and the tests beside it. A commit keeps
      // its journal far longer than this pause (FULL syncs; measured on this drive in Release: 13
      // commits of 64-476 ms, median 236 ms; longer under the sanitizers), so the wait still
      // lands inside one.
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_TRUE(child.kill_now()) << "the run ended before the kill at moment " << static_cast<int>(moment);
    const SemanticMap left = load_map(out);  // rolls an interrupted commit back
    EXPECT_GE(left.num_submaps(), std::max<std::size_t>(seen, 1));
    for (const SubmapInfo& s : left.submaps()) {
      left.read_submap(s.id, [&](const Submap& kept) {
        full.read_submap(s.id, [&](const Submap& reference) {
          EXPECT_EQ(kept.voxels().occupancy().num_known_voxels(), reference.voxels().occupancy().num_known_voxels());
          EXPECT_EQ(kept.voxels().semantics().size(), reference.voxels().semantics().size());
          EXPECT_TRUE(kept.T_world_submap().isApprox(reference.T_world_submap()));
        });
      });
    }
    const auto resumed = run_cli(map_command(out) + " --resume", 300);
    ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
    EXPECT_NE(resumed.output.find("resuming"), std::string::npos) << resumed.output;
    const SemanticMap continued = load_map(out);
    EXPECT_EQ(continued.num_submaps(), n);
    testing::expect_same_index_cells(continued, full);
  }
}

TEST_F(Checkpoints, ResumeRefusesAnotherConfigurationAndAMissingFile) {
  const auto missing = run_cli(map_command(file("nothing-here.svdb")) + " --resume");
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  ASSERT_EQ(run_cli(map_command(file("small.svdb")) + " --max-scans 40").exit_code, 0);
  const auto other = run_cli(map_command(file("small.svdb")) + " --resume --voxel-size 0.5");
  EXPECT_EQ(other.exit_code, 1) << other.output;
  EXPECT_NE(other.output.find("--voxel-size"), std::string::npos) << other.output;
  // The same embedding space (model id) from an encoder with other failure modes, or another
  // fusion rule, would mix two maps in one file.
  const auto clean = run_cli(map_command(file("small.svdb")) + " --resume --sim-encoder clean");
  EXPECT_EQ(clean.exit_code, 1) << clean.output;
  EXPECT_NE(clean.output.find("--sim-encoder"), std::string::npos) << clean.output;
  const auto rule = run_cli(map_command(file("small.svdb")) + " --resume --fusion-weighting quality");
  EXPECT_EQ(rule.exit_code, 1) << rule.output;
  EXPECT_NE(rule.output.find("--fusion-weighting"), std::string::npos) << rule.output;
}

}  // namespace
}  // namespace slamvdb
