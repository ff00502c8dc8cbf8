// `slam --realtime`: scans are taken at their stamps on the wall clock. At the SIMULATED drive's
// own rate (10 Hz, recorded as an MCAP by the independent fixture writer) the run lasts at least
// the drive's span and, when it keeps up, maps exactly what the run as fast as possible maps. With
// the stamps far closer than the odometry can follow, scans that a newer one overtook are skipped
// and counted, and the scans taken are mapped.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb {
namespace slam_realtime_test {

namespace fs = std::filesystem;
using testing::quote_path;

class SlamRealtime : public ::testing::Test {
 protected:
  static fs::path& dir() {
    static fs::path d;
    return d;
  }
  static void SetUpTestSuite() {
    dir() = fs::temp_directory_path() / ("slamvdb-slam-realtime-test-" + std::to_string(::getpid()));
    fs::remove_all(dir());
    synth::SynthConfig config = testing::recording_sequence_config();
    config.length_m = 10;  // 2 s of scans at 5 m/s
    testing::write_recording_sequence(dir() / "seq", config);
  }
  static void TearDownTestSuite() { fs::remove_all(dir()); }
  static testing::CommandResult slamvdb(const std::string& args) {
    return testing::run_command("exec " + quote_path(SLAMVDB_CLI_PATH) + " " + args + " 2>&1", 600.0);
  }
  static std::vector<double> stamps(const fs::path& times) {
    std::vector<double> out;
    std::ifstream in(times);
    for (double t; in >> t;) out.push_back(t);
    return out;
  }
  struct Kept {
    std::size_t kept = 0, of = 0, overtaken = 0, tracked = 0;
  };
  // "real time: kept up with A of B scans (K overtaken ...)" and "slam of X: N scans".
  static Kept kept(const std::string& output) {
    Kept k;
    std::smatch m;
    if (std::regex_search(output, m, std::regex(R"(real time: kept up with (\d+) of (\d+) scans( \((\d+) overtaken)?)"))) {
      k.kept = std::stoul(m[1]), k.of = std::stoul(m[2]);
      if (m[4].matched) k.overtaken = std::stoul(m[4]);
    }
    if (std::regex_search(output, m, std::regex(R"(slam of .*: (\d+) scans)"))) k.tracked = std::stoul(m[1]);
    return k;
  }
};

TEST_F(SlamRealtime, PacesARecordingByItsStampsAndMapsWhatItKeptUpWith) {
  const fs::path mcap = dir() / "drive.mcap";
  ASSERT_TRUE(testing::run_fixture_writer("write_mcap.mjs", quote_path(dir() / "seq") + " " + quote_path(mcap) +
                                                                " --profile ros2"));
  const std::vector<double> t = stamps(dir() / "seq" / "times.txt");
  ASSERT_GE(t.size(), 20u);
  auto r = slamvdb("slam " + quote_path(mcap) + " -o " + quote_path(dir() / "fast.svdb") + " --features none");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("real time:"), std::string::npos) << r.output;
  const auto start = std::chrono::steady_clock::now();
  r = slamvdb("slam " + quote_path(mcap) + " -o " + quote_path(dir() / "paced.svdb") + " --features none --realtime");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_GE(seconds, t.back() - t.front()) << r.output;
  const Kept k = kept(r.output);
  EXPECT_EQ(k.of, t.size()) << r.output;
  EXPECT_EQ(k.tracked + k.overtaken, t.size()) << r.output;
  // The odometry keeps up at 10 Hz in a Release build on an idle machine; under a sanitizer (or a
  // loaded machine) it may not, and then the maps differ by the scans it skipped.
  if (k.overtaken == 0 && k.kept == t.size()) {
    EXPECT_EQ(testing::occupied_voxels(dir() / "paced.svdb"), testing::occupied_voxels(dir() / "fast.svdb"));
  }
}

TEST_F(SlamRealtime, ScansOvertakenWhileTheOdometryWorksAreSkippedAndCounted) {
  // The same drive with its scan stamps 0.1 ms apart (10 kHz): no odometry registers a scan that
  // fast (5-20 ms here), so scans are overtaken, as a driver queue of one would not give it every
  // scan. Nothing overtakes the last scan, so it is always taken (the first may not be: under a
  // sanitizer, reading it takes longer than 0.1 ms and the second has arrived by then).
  const fs::path fast = dir() / "seq10khz";
  fs::remove_all(fast);
  fs::copy(dir() / "seq", fast, fs::copy_options::recursive);
  const std::vector<double> t = stamps(fast / "times.txt");
  {
    std::ofstream out(fast / "times.txt");
    out.precision(17);
    for (const double s : t) out << t.front() + (s - t.front()) / 1000 << "\n";
  }
  const fs::path poses = dir() / "overtaken-poses.txt";
  const auto r = slamvdb("slam " + quote_path(fast) + " -o " + quote_path(dir() / "overtaken.svdb") +
                         " --features none --realtime --poses-out " + quote_path(poses) + " --format tum");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Kept k = kept(r.output);
  EXPECT_EQ(k.of, t.size()) << r.output;
  EXPECT_GT(k.overtaken, 0u) << r.output;
  EXPECT_EQ(k.tracked + k.overtaken, t.size()) << r.output;
  // One TUM row per scan taken, the last scan's among them.
  const std::vector<double> rows = stamps(poses);  // every number of the file, 8 per row
  ASSERT_EQ(rows.size(), 8 * k.tracked) << r.output;
  EXPECT_NEAR(rows[rows.size() - 8], t.front() + (t.back() - t.front()) / 1000, 2e-5) << r.output;  // 1e-4 apart
  EXPECT_GT(testing::occupied_voxels(dir() / "overtaken.svdb").size(), 0u);
}

}  // namespace slam_realtime_test
}  // namespace slamvdb
