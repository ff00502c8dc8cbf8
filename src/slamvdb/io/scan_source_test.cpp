// The scan inputs and trajectory files of `slamvdb odometry`, and the odometry / eval-trajectory
// commands end to end on a SIMULATED drive written as a folder of PCD files.
#include "slamvdb/io/scan_source.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "slamvdb/io/pcd.hpp"
#include "slamvdb/io/trajectory_io.hpp"
#include "slamvdb/synth/lidar_sim.hpp"
#include "slamvdb/synth/world.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

using slamvdb::testing::error_of;
using slamvdb::testing::TempDir;

int run_cli_to(const std::string& args, std::string* output) {
  const std::string log = ::testing::TempDir() + "/slamvdb_loc_cli.log";
  const int rc = std::system((std::string(SLAMVDB_CLI_PATH) + " " + args + " > '" + log + "' 2>&1").c_str());
  std::ifstream in(log);
  std::stringstream ss;
  ss << in.rdbuf();
  *output = ss.str();
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

TEST(TrajectoryIo, RoundTripsKittiAndTumAndDetectsTheFormat) {
  TempDir dir;
  std::vector<double> stamps{10.0, 10.1, 10.2};
  std::vector<Pose> poses(3, Pose::Identity());
  poses[1].translation() = Vec3d(1, 2, 3);
  poses[2].linear() = Eigen::AngleAxisd(0.3, Vec3d::UnitZ()).toRotationMatrix();
  for (const auto format : {PoseFormat::kKitti, PoseFormat::kTum}) {
    write_trajectory(dir.path / "p.txt", stamps, poses, format);
    const StampedPoses back = read_trajectory(dir.path / "p.txt");
    EXPECT_EQ(back.format, format);
    ASSERT_EQ(back.poses.size(), 3u);
    for (int i = 0; i < 3; ++i) EXPECT_TRUE(back.poses[i].isApprox(poses[i], 1e-6));
    if (format == PoseFormat::kTum) {
      EXPECT_DOUBLE_EQ(back.stamps[2], 10.2);
    }
  }
  std::ofstream(dir.path / "bad.txt") << "1 2 3\n";
  EXPECT_NE(error_of([&] { read_trajectory(dir.path / "bad.txt"); }).find("bad.txt:1"), std::string::npos);
}

TEST(ScanSource, FoldersOfScansAndTheirErrors) {
  TempDir dir;
  EXPECT_NE(error_of([&] { open_scan_source(dir.path, 10.0); }).find("holds no scans"), std::string::npos);
  write_pcd(dir.path / "2.pcd", PcdCloud{{Vec3f(1, 2, 3)}, {}, {}});
  write_pcd(dir.path / "10.pcd", PcdCloud{{Vec3f(4, 5, 6)}, {}, {}});
  ScanSource s = open_scan_source(dir.path, 5.0);
  ASSERT_EQ(s.scans.size(), 2u);
  EXPECT_EQ(s.scans[1].path.filename(), "10.pcd");  // numeric order
  EXPECT_DOUBLE_EQ(s.scans[1].stamp, 0.2);
  EXPECT_EQ(load_scan_points(s.scans[1]).points.front(), Vec3f(4, 5, 6));
  std::ofstream(dir.path / "times.txt") << "3.0\n3.5\n";
  EXPECT_DOUBLE_EQ(open_scan_source(dir.path, 5.0).scans[1].stamp, 3.5);
  std::ofstream(dir.path / "x.bin") << "";
  EXPECT_NE(error_of([&] { open_scan_source(dir.path, 5.0); }).find("both"), std::string::npos);
}

TEST(OdometryCommand, RunsOnAFolderOfPcdScansAndIsEvaluated) {
  TempDir dir;
  synth::SynthConfig config;
  config.length_m = 40.0;
  config.speed_mps = 10.0;
  config.lidar.columns = 512;
  const synth::SynthWorld world = synth::build_synthetic_world(config);
  const auto rays = config.lidar.ray_directions();
  const auto scans = dir.path / "scans";
  std::filesystem::create_directories(scans);
  std::vector<double> stamps;
  std::vector<Pose> truth;
  for (std::size_t i = 0; i < 40; ++i) {
    const auto s = synth::simulate_scan(*world.scene, config.lidar, rays, world.scan_poses[i], 1, i, false);
    PcdCloud cloud;
    for (const auto& p : s.points) cloud.points.push_back(p.head<3>());
    if (i == 20) cloud.points.assign(cloud.points.size(), Vec3f::Constant(std::nanf("")));  // a broken scan
    write_pcd(scans / fmt::format("{:06d}.pcd", i), cloud, i % 2 ? PcdEncoding::kBinaryCompressed : PcdEncoding::kBinary);
    stamps.push_back(world.scan_stamps[i]);
    truth.push_back(world.scan_poses[i]);
  }
  write_trajectory(dir.path / "truth.txt", stamps, truth, PoseFormat::kTum);
  std::string out;
  const std::string poses = (dir.path / "poses.txt").string();
  ASSERT_EQ(run_cli_to("odometry '" + scans.string() + "' -o '" + poses + "' --format tum --rate 10 --loop-closure --json '" +
                        (dir.path / "s.json").string() + "'", &out), 0) << out;
  EXPECT_NE(out.find("not registered (too few valid points): 1"), std::string::npos) << out;
  EXPECT_NE(out.find("loops"), std::string::npos) << out;
  // The folder has no times.txt: stamps are i / 10 Hz, so pair the truth by index (KITTI).
  write_trajectory(dir.path / "truth_kitti.txt", stamps, truth, PoseFormat::kKitti);
  ASSERT_EQ(run_cli_to("eval-trajectory '" + poses + "' '" + (dir.path / "truth_kitti.txt").string() + "' --png '" +
                        (dir.path / "plot.png").string() + "' --json '" + (dir.path / "m.json").string() + "'", &out), 0)
      << out;
  EXPECT_NE(out.find("ATE  rmse 0.0"), std::string::npos) << out;  // centimetres
  EXPECT_TRUE(std::filesystem::exists(dir.path / "plot.png"));
  // Usage errors exit with CLI11's usage code (main.cpp: app.exit), runtime errors with 1, before any work.
  const auto usage_error = [](int rc) { return rc != 0 && rc != 1; };
  EXPECT_TRUE(usage_error(run_cli_to("odometry '" + scans.string() + "' -o /nonexistent/dir/p.txt", &out))) << out;
  EXPECT_TRUE(usage_error(run_cli_to("odometry '" + scans.string() + "' -o '" + poses + "' --format xyz", &out))) << out;
  std::filesystem::create_directories(dir.path / "empty");
  EXPECT_EQ(run_cli_to("odometry '" + (dir.path / "empty").string() + "' -o '" + poses + "'", &out), 1) << out;
  EXPECT_NE(out.find("holds no scans"), std::string::npos) << out;
  EXPECT_EQ(run_cli_to("eval-trajectory '" + poses + "' '" + (dir.path / "s.json").string() + "'", &out), 1) << out;
}

}  // namespace
}  // namespace slamvdb
