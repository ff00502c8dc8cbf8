// Pose sources: the same poses from a KITTI file, a TUM file and the ground truth give one map.
#include "slamvdb/pipeline/pose_source.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <fstream>
#include <iostream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/pipeline_fixture.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;
using testing::MappingPipelineTest;

// Share of the cells of `a` that `b` has with the same count and embedding.
double identical_share(const SemanticMap& a, const SemanticMap& b) {
  const auto ca = testing::index_cells(a), cb = testing::index_cells(b);
  std::size_t same = 0;
  for (const auto& [key, cell] : ca) {
    const auto it = cb.find(key);
    if (it != cb.end() && it->second.count == cell.count && it->second.embedding == cell.embedding) ++same;
  }
  return ca.empty() ? 0.0 : static_cast<double>(same) / static_cast<double>(std::max(ca.size(), cb.size()));
}

TEST_F(MappingPipelineTest, TumAndKittiPoseFilesGiveTheGroundTruthMap) {
  const Sequence seq = read_sequence(dir_);
  const fs::path kitti = dir_ / "poses_kitti_copy.txt", tum = dir_ / "poses_tum_copy.txt";
  write_trajectory(kitti, seq.poses.stamps(), seq.poses.poses(), PoseFormat::kKitti);
  write_trajectory(tum, seq.poses.stamps(), seq.poses.poses(), PoseFormat::kTum);
  const Trajectory from_kitti = PoseFile(kitti).trajectory(seq), from_tum = PoseFile(tum).trajectory(seq);
  ASSERT_EQ(from_kitti.size(), seq.scans.size());
  ASSERT_EQ(from_tum.size(), seq.scans.size());
  EXPECT_EQ(from_tum.stamps(), seq.poses.stamps());  // TUM stamps are written to round-trip exactly

  PipelineOptions o = options();
  o.max_scans = 30;
  auto map_with = [&](const Trajectory* poses) {
    EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                                EncoderFeatureSource::Input::kLabels);
    o.poses = poses;
    PipelineReport report;
    SemanticMap map = build_map(seq, &source, o, report);
    EXPECT_EQ(report.scans_integrated, 30u);
    return map;
  };
  const SemanticMap truth = map_with(nullptr), k = map_with(&from_kitti), t = map_with(&from_tum);
  // The files hold 9-10 significant digits: a handful of cells on a voxel boundary may differ.
  EXPECT_GT(identical_share(t, k), 0.995);
  EXPECT_GT(identical_share(k, truth), 0.995);
  EXPECT_EQ(t.num_submaps(), truth.num_submaps());
}

TEST_F(MappingPipelineTest, PoseFilesThatDoNotFitAreErrorsNamingTheFile) {
  const Sequence seq = read_sequence(dir_);
  const fs::path kitti = dir_ / "too_many.txt", tum = dir_ / "backwards.txt";
  std::vector<Pose> poses(seq.scans.size() + 1, Pose::Identity());
  std::vector<double> stamps(poses.size());
  write_trajectory(kitti, stamps, poses, PoseFormat::kKitti);
  try {
    PoseFile(kitti).trajectory(seq);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("too_many.txt"), std::string::npos) << e.what();
  }
  std::ofstream(tum) << "2.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n";
  try {
    PoseFile(tum).trajectory(seq);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("backwards.txt"), std::string::npos) << e.what();
  }
  // A KITTI file with fewer rows leaves the last scans without a pose: counted, not fatal.
  poses.resize(10), stamps.resize(10);
  write_trajectory(kitti, stamps, poses, PoseFormat::kKitti);
  const Trajectory short_poses = PoseFile(kitti).trajectory(seq);
  PipelineOptions o = options();
  o.max_scans = 20;
  o.poses = &short_poses;
  PipelineReport report;
  build_map(seq, nullptr, o, report);
  EXPECT_EQ(report.scans_integrated, 10u);
  EXPECT_EQ(report.scans_without_pose, 10u);
}

TEST_F(MappingPipelineTest, MapCommandTakesATumPoseFile) {
  const Sequence seq = read_sequence(dir_);
  const fs::path tum = dir_ / "cli_poses.tum", out = dir_ / "cli_tum.svdb";
  write_trajectory(tum, seq.poses.stamps(), seq.poses.poses(), PoseFormat::kTum);
  const auto r = testing::run_cli(fmt::format("map {} -o {} --poses {} --pose-format tum --max-scans 20 --dim 16 "
                                              "--feature-size 64x40", testing::shell_quote(dir_.string()),
                                              testing::shell_quote(out.string()), testing::shell_quote(tum.string())));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("TUM pose file"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("20 integrated of 20"), std::string::npos) << r.output;
}

// The project's own odometry behind the same interface: one pose per scan, placed at the first
// ground-truth pose and close to the rest of them (the simulated drive is 30 m).
TEST_F(MappingPipelineTest, OwnOdometryIsAPoseSourceCloseToTheGroundTruth) {
  const Sequence seq = read_sequence(dir_);
  std::size_t progress_calls = 0;
  OdometryPoses source(TrackingOptions{}, [&](std::size_t, std::size_t, const TrackingResult&) { ++progress_calls; });
  const Trajectory own = source.trajectory(seq);
  ASSERT_EQ(own.size(), seq.scans.size());
  EXPECT_EQ(progress_calls, seq.scans.size());
  EXPECT_TRUE(own.poses().front().isApprox(*seq.poses.at(seq.scans.front().stamp), 1e-9));
  double worst = 0;
  for (std::size_t i = 0; i < own.size(); ++i)
    worst = std::max(worst, (own.poses()[i].translation() - seq.poses.at(own.stamps()[i])->translation()).norm());
  std::cout << "own odometry on the SIMULATED 30 m drive: worst position error " << worst << " m\n";
  // 0.09 m on 1024-column scans, 0.34 m on the sanitizer run's 256-column ones (test_scale.hpp); a
  // source that lost the track or the placement is metres off.
  EXPECT_LT(worst, 0.6);
  EXPECT_NE(source.describe().find(fmt::format("{} scans registered", seq.scans.size())), std::string::npos)
      << source.describe();
}

TEST_F(MappingPipelineTest, MapCommandMapsOnItsOwnOdometry) {
  const fs::path out = dir_ / "cli_odometry.svdb";
  const std::string common = fmt::format("map {} -o {} --max-scans 20 --dim 16 --feature-size 64x40",
                                         testing::shell_quote(dir_.string()), testing::shell_quote(out.string()));
  const auto r = testing::run_cli(common + " --odometry --no-loop-closure");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("poses: the project's LiDAR odometry ("), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("20 integrated of 20"), std::string::npos) << r.output;
  const auto both = testing::run_cli(common + " --odometry --poses " + testing::shell_quote((dir_ / "poses.txt").string()));
  EXPECT_EQ(both.exit_code, 2) << both.output;
  EXPECT_EQ(testing::run_cli(common + " --no-loop-closure").exit_code, 2);
}

}  // namespace
}  // namespace slamvdb
