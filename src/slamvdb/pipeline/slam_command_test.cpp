// `slamvdb slam` end to end on a simulated drive that closes a loop: the map built on the
// project's own poses (odometry, loop closure, submaps moved and merged) agrees with the map built
// on the ground-truth poses, and bad input is refused before any work.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "slamvdb/eval/map_comparison.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::run_command;
using testing::shell_quote;

// A simulated 100 m drive, revisited after 75 m (a loop to close), in a temporary directory, and
// the options both tests map it with. Under the sanitizers (slamvdb/testing/test_scale.hpp) the
// same loop is driven at twice the speed: half the scans (1 m apart, as LoopClosingMapper's loop),
// half the ray casting, registration and mapping, which were most of the two tests' 240 s there;
// and 256 LiDAR columns, 64x40 images (the tests compare geometry; images only feed the fusion):
// the synthesis 13 -> 6 CPU-s, `slam` 62 -> 47 CPU-s under ASan (measured with the CLI).
struct LoopDrive {
  testing::TempDir tmp;
  fs::path seq = tmp.path / "seq";
  std::string cli = shell_quote(SLAMVDB_CLI_PATH);
  std::string common = " --feature-size 48x32 --dim 16 --submap-length 20 ";
  LoopDrive() {
    synth::SynthConfig config;
    config.seed = 2;
    config.length_m = 100.0;
    config.min_loop_m = 70.0;
    config.image_width = testing::test_size(160, 64);
    config.image_height = testing::test_size(100, 40);
    config.speed_mps = testing::test_size(5.0, 10.0);
    config.lidar.columns = testing::test_size(1024, 256);
    synth::write_synthetic_sequence(config, seq, true);
  }
  std::size_t scans() const { return read_sequence(seq).scans.size(); }
};

TEST(SlamCommand, MapOnOwnPosesAgreesWithTheGroundTruthMap) {
  const LoopDrive drive;
  const testing::TempDir& tmp = drive.tmp;
  const std::string &seq_dir = drive.seq.string(), &cli = drive.cli, &common = drive.common;
  const fs::path slam_map = tmp.path / "slam.svdb", truth_map = tmp.path / "truth.svdb", poses = tmp.path / "p.txt";
  const auto slam = run_command(cli + " slam " + shell_quote(seq_dir) + " -o " + shell_quote(slam_map.string()) +
                                " --poses-out " + shell_quote(poses.string()) + common + " 2>&1", 300);
  ASSERT_EQ(slam.exit_code, 0) << slam.output;
  const auto truth = run_command(cli + " map " + shell_quote(seq_dir) + " -o " + shell_quote(truth_map.string()) +
                                 common + " 2>&1", 300);
  ASSERT_EQ(truth.exit_code, 0) << truth.output;
  std::cout << slam.output.substr(slam.output.find("slam of"));

  EXPECT_EQ(slam.output.find("0 accepted"), std::string::npos) << slam.output;  // a loop was closed
  EXPECT_NE(slam.output.find("merged into"), std::string::npos) << slam.output;  // and submaps merged
  EXPECT_NE(slam.output.find("corrections while mapping"), std::string::npos) << slam.output;
  EXPECT_EQ(slam.output.find("moved by 0 corrections"), std::string::npos) << slam.output;  // moved as loops closed
  std::ifstream in(poses);
  std::size_t lines = 0;
  for (std::string line; std::getline(in, line);) lines += !line.empty();
  EXPECT_EQ(lines, drive.scans());  // one corrected pose per scan
  EXPECT_GE(lines, testing::test_size(200u, 100u));

  const SemanticMap a = load_map(slam_map), b = load_map(truth_map);
  EXPECT_NE(a.info().source.find("slam"), std::string::npos);
  EXPECT_LT(a.num_submaps(), b.num_submaps());  // merged
  const OccupiedCells a_cells = occupied_world_cells(a), b_cells = occupied_world_cells(b);  // read once each
  const double iou = occupied_iou(a_cells, b_cells, 1), exact = occupied_iou(a_cells, b_cells, 0);
  std::cout << "occupied-voxel IoU with the ground-truth map: " << exact << " exact, " << iou << " within one voxel\n";
  EXPECT_GT(iou, 0.9);
  // Under the sanitizers the unloading below is left to Checkpoints.CorrectionsReachSubmapsThatLeftMemory
  // (in process, same code): a third mapping of the drive here was 140 s of the ASan run.
  if (testing::sanitizer_test_scale()) return;

  // Far submaps out of memory while mapping (the file grows as in `map`; corrections move them
  // where they wait, merges read them back): the same map.
  const fs::path unloaded_map = tmp.path / "unloaded.svdb";
  const auto unloaded = run_command(cli + " slam " + shell_quote(seq_dir) + " -o " + shell_quote(unloaded_map.string()) +
                                    common + " --unload-radius 12 2>&1", 300);
  ASSERT_EQ(unloaded.exit_code, 0) << unloaded.output;
  EXPECT_NE(unloaded.output.find("times one left memory"), std::string::npos) << unloaded.output;
  EXPECT_NE(unloaded.output.find("merged into"), std::string::npos) << unloaded.output;
  const SemanticMap c = load_map(unloaded_map);
  EXPECT_EQ(c.num_submaps(), a.num_submaps());
  EXPECT_GT(occupied_iou(occupied_world_cells(c), a_cells, 1), 0.99);
}

// The number printed right after `label` in `text` (NaN when absent).
double number_after(const std::string& text, const std::string& label) {
  const std::size_t at = text.find(label);
  return at == std::string::npos ? std::nan("") : std::atof(text.c_str() + at + label.size());
}

// Loop closure while mapping, against an odometry that drifts: the drive above with a SIMULATED
// heading drift of 4 degrees per 100 m. Without loop closure the revisited place is mapped twice,
// apart; with it the submaps are moved back while mapping goes on.
TEST(SlamCommand, CorrectionsWhileMappingRemoveSimulatedDrift) {
  const LoopDrive drive;
  const testing::TempDir& tmp = drive.tmp;
  const std::string &seq_dir = drive.seq.string(), &cli = drive.cli, &common = drive.common;
  auto slam = [&](const std::string& name, const std::string& extra) {
    const fs::path out = tmp.path / name;
    const auto r = run_command(cli + " slam " + shell_quote(seq_dir) + " -o " + shell_quote(out.string()) +
                                   common + "--sim-odometry-drift 4 " + extra + " 2>&1", 300);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return std::make_pair(load_map(out), r.output);
  };
  const auto [closed, closed_output] = slam("closed.svdb", "");
  std::cout << closed_output.substr(closed_output.find("slam of"));
  EXPECT_NE(closed_output.find("SIMULATED"), std::string::npos);
  EXPECT_NE(closed.info().source.find("SIMULATED drift"), std::string::npos);
  // The drift is large (0.27 m ATE after alignment, measured), loop closure takes most of it away.
  const double ate_odometry = number_after(closed_output, "ATE rmse "),
               ate_closed = number_after(closed_output, "m with odometry only, ");
  EXPECT_GT(ate_odometry, 0.15) << closed_output;
  EXPECT_LT(ate_closed, 0.3 * ate_odometry) << closed_output;
  // Submaps were moved by about that much while mapping went on.
  EXPECT_GT(number_after(closed_output, "largest shift "), 0.3) << closed_output;
  // The map comparison below maps the drive twice more: an accuracy check for the Release suite.
  // Under the sanitizers the corrections' code has run above (slamvdb/testing/test_scale.hpp).
  if (testing::sanitizer_test_scale()) return;

  const auto [drifted, drifted_output] = slam("drifted.svdb", "--no-loop-closure");
  const fs::path truth_path = tmp.path / "truth.svdb";
  const auto truth_run = run_command(cli + " map " + shell_quote(seq_dir) + " -o " +
                                     shell_quote(truth_path.string()) + common + " 2>&1", 300);
  ASSERT_EQ(truth_run.exit_code, 0) << truth_run.output;
  const SemanticMap truth = load_map(truth_path);
  // And the map shows it: the drifted map's second pass does not lie on the first.
  const double iou_closed = occupied_iou(closed, truth, 1), iou_drifted = occupied_iou(drifted, truth, 1);
  std::cout << "occupied-voxel IoU within one voxel with the ground-truth map: " << iou_closed << " with loop closure, "
            << iou_drifted << " without\n";
  EXPECT_GT(iou_closed, 0.85);
  EXPECT_GT(iou_closed, iou_drifted + 0.1);
}

TEST(SlamCommand, RefusesBadInputBeforeWork) {
  testing::TempDir tmp;
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH);
  fs::create_directories(tmp.path / "empty");
  const auto empty = run_command(cli + " slam " + shell_quote((tmp.path / "empty").string()) + " -o " +
                                 shell_quote((tmp.path / "m.svdb").string()) + " 2>&1");
  EXPECT_EQ(empty.exit_code, 1) << empty.output;
  EXPECT_FALSE(fs::exists(tmp.path / "m.svdb"));
  const auto no_dir = run_command(cli + " slam " + shell_quote((tmp.path / "empty").string()) +
                                  " -o /no/such/dir/m.svdb 2>&1");
  EXPECT_EQ(no_dir.exit_code, 2) << no_dir.output;
  const auto bad = run_command(cli + " slam " + shell_quote((tmp.path / "empty").string()) + " -o " +
                               shell_quote((tmp.path / "m.svdb").string()) + " --keyframe-distance nan 2>&1");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  const auto bad_drift = run_command(cli + " slam " + shell_quote((tmp.path / "empty").string()) + " -o " +
                                     shell_quote((tmp.path / "m.svdb").string()) + " --sim-odometry-drift inf 2>&1");
  EXPECT_EQ(bad_drift.exit_code, 2) << bad_drift.output;
}

}  // namespace
}  // namespace slamvdb
