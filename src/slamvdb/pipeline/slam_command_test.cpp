// `slamvdb slam` end to end on a simulated drive that closes a loop: the map built on the
// project's own poses (odometry, loop closure, submaps moved and merged) agrees with the map built
// on the ground-truth poses, and bad input is refused before any work.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "slamvdb/eval/map_comparison.hpp"
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

TEST(SlamCommand, MapOnOwnPosesAgreesWithTheGroundTruthMap) {
  testing::TempDir tmp;
  const fs::path seq = tmp.path / "seq";
  synth::SynthConfig config;
  config.seed = 2;
  config.length_m = 100.0;
  config.min_loop_m = 70.0;  // revisited after 75 m: a loop to close
  config.image_width = 160;
  config.image_height = 100;
  config.lidar.columns = testing::test_size(1024, 512);  // slamvdb/testing/test_scale.hpp
  synth::write_synthetic_sequence(config, seq, true);

  const std::string cli = shell_quote(SLAMVDB_CLI_PATH);
  const std::string common = " --feature-size 48x32 --dim 16 --submap-length 20 ";
  const fs::path slam_map = tmp.path / "slam.svdb", truth_map = tmp.path / "truth.svdb", poses = tmp.path / "p.txt";
  const auto slam = run_command(cli + " slam " + shell_quote(seq.string()) + " -o " + shell_quote(slam_map.string()) +
                                " --poses-out " + shell_quote(poses.string()) + common + " 2>&1", 300);
  ASSERT_EQ(slam.exit_code, 0) << slam.output;
  const auto truth = run_command(cli + " map " + shell_quote(seq.string()) + " -o " + shell_quote(truth_map.string()) +
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
  EXPECT_EQ(lines, 204u);  // one corrected pose per scan

  const SemanticMap a = load_map(slam_map), b = load_map(truth_map);
  EXPECT_NE(a.info().source.find("slam"), std::string::npos);
  EXPECT_LT(a.num_submaps(), b.num_submaps());  // merged
  const double iou = occupied_iou(a, b, 1), exact = occupied_iou(a, b, 0);
  std::cout << "occupied-voxel IoU with the ground-truth map: " << exact << " exact, " << iou << " within one voxel\n";
  EXPECT_GT(iou, 0.9);
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
}

}  // namespace
}  // namespace slamvdb
