// When not one scan can be registered (every scan empty or with too few valid points), the
// project's odometry gives no poses: `odometry`, `slam` and `map --odometry` fail (exit 1) saying
// so and why, instead of reporting "registered 0" and writing guessed poses with exit 0.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/pcd.hpp"
#include "slamvdb/pipeline/lidar_tracking.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::error_of;
using testing::quote_path;
using testing::run_cli;
using testing::TempDir;

// `n` points on a ring 5 m around the sensor (valid: finite, within 1..100 m).
std::vector<Vec3f> ring_points(int n) {
  std::vector<Vec3f> points;
  for (int i = 0; i < n; ++i) {
    const float a = 6.2831853f * static_cast<float>(i) / static_cast<float>(std::max(n, 1));
    points.emplace_back(5.0f * std::cos(a), 5.0f * std::sin(a), 0.1f * static_cast<float>(i % 7));
  }
  return points;
}

void expect_mentions(const std::string& text, std::initializer_list<std::string> parts) {
  for (const std::string& part : parts) EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' in: " << text;
}

TEST(UnregisteredScans, TrackerSaysWhyNoScanCouldBeRegistered) {
  TrackingOptions options;
  options.loop_closure = false;
  LidarTracker tracker(options);
  tracker.track(0.0, {}, nullptr, "a");
  tracker.track(0.1, ring_points(1), nullptr, "b");
  tracker.track(0.2, ring_points(50), nullptr, "c");
  EXPECT_EQ(tracker.result().registered(), 0u);
  expect_mentions(error_of([&] { tracker.require_registered("drive", 2); }),
                  {"drive: no scan could be registered (5 scans: 2 unreadable, 1 empty, 2 too few valid points)",
                   "at least 100 valid points"});
  tracker.track(0.3, ring_points(500), nullptr, "d");  // the first usable scan defines the odometry frame
  EXPECT_EQ(tracker.result().registered(), 1u);
  EXPECT_NO_THROW(tracker.require_registered("drive"));
}

TEST(UnregisteredScans, OdometryOnAFolderOfEmptyAndOnePointScansIsAnError) {
  TempDir dir;
  const fs::path scans = dir.path / "scans", poses = dir.path / "poses.txt";
  fs::create_directories(scans);
  for (int i = 0; i < 4; ++i) write_pcd(scans / fmt::format("{:02d}.pcd", i), PcdCloud{ring_points(i % 2), {}, {}});
  const auto r = run_cli(fmt::format("odometry {} -o {}", quote_path(scans), quote_path(poses)));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  expect_mentions(r.output, {"no scan could be registered (4 scans: 2 empty, 2 too few valid points)", scans.string()});
  EXPECT_FALSE(fs::exists(poses)) << "guessed poses were written";
}

// A short SIMULATED sequence (5 scans) whose every scan keeps only its first point (and label).
TEST(UnregisteredScans, SlamAndMapOnOwnOdometryRefuseOnePointScans) {
  TempDir dir;
  const fs::path seq = dir.path / "seq";
  synth::SynthConfig config;
  config.length_m = 2.0;
  config.image_width = 80;
  config.image_height = 50;
  config.lidar.columns = 128;
  synth::write_synthetic_sequence(config, seq, true);
  std::size_t scans = 0;
  for (const auto& entry : fs::recursive_directory_iterator(seq)) {
    const auto ext = entry.path().extension();
    if (ext != ".bin" && ext != ".label") continue;
    const std::size_t keep = ext == ".bin" ? 16 : 4;  // x y z intensity floats; one uint32 label
    fs::resize_file(entry.path(), keep);
    scans += ext == ".bin";
  }
  ASSERT_GE(scans, 3u);
  ASSERT_LE(scans, 10u);  // more in a row would lose the odometry first (max_consecutive_failures)
  const std::string common = " --dim 16 --feature-size 32x20";
  const auto slam = run_cli(fmt::format("slam {} -o {}{}", quote_path(seq), quote_path(dir.path / "s.svdb"), common));
  EXPECT_EQ(slam.exit_code, 1) << slam.output;
  expect_mentions(slam.output, {fmt::format("no scan could be registered ({} scans: {} too few valid points)", scans,
                                            scans)});
  EXPECT_FALSE(fs::exists(dir.path / "s.svdb"));
  const auto map = run_cli(fmt::format("map {} -o {} --odometry{}", quote_path(seq), quote_path(dir.path / "m.svdb"),
                                       common));
  EXPECT_EQ(map.exit_code, 1) << map.output;
  expect_mentions(map.output, {"no scan could be registered", "too few valid points"});
  EXPECT_FALSE(fs::exists(dir.path / "m.svdb"));
}

}  // namespace
}  // namespace slamvdb
