// Every numeric option of every command is checked before work starts: a bad value is a usage
// error (exit code 2) naming the option; runtime failures exit 1 with a message naming the file.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fstream>

#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/tiny_rellis.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;
using testing::run_command;
using testing::shell_quote;

CommandResult cli(const std::string& args) { return testing::run_cli(args, 60.0); }

class CliOptionBounds : public ::testing::Test {
 protected:
  void SetUp() override { testing::TinyRellis{}.write(tmp_.path / "seq"); }
  std::string seq() const { return shell_quote((tmp_.path / "seq").string()); }
  std::string out(const char* name) const { return shell_quote((tmp_.path / name).string()); }
  void expect_usage_error(const std::string& args, const std::string& mention) {
    const CommandResult r = cli(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(mention), std::string::npos) << args << "\n" << r.output;
  }
  testing::TempDir tmp_;
};

TEST_F(CliOptionBounds, MapRefusesOutOfRangeValuesNamingTheOption) {
  const std::string map = "map " + seq() + " -o " + out("m.svdb") + " ";
  // One of each kind of check (each run of the CLI costs about a second of libtorch start-up; the
  // validators themselves are unit-tested in apps/tests/option_checks_test.cpp).
  for (const auto& [args, mention] : std::vector<std::pair<std::string, std::string>>{
           {"--max-depth nan", "--max-depth: nan is not a finite number"},
           {"--max-depth 1e9", "--max-depth"},
           {"--max-clearing-range 1e13", "--max-clearing-range"},
           {"--max-clearing-range 500 --voxel-size 0.05", "10000 voxels"},
           {"--min-range 50 --max-range 40", "--min-range 50 must be below --max-range 40"},
           {"--voxel-size 0.001", "--voxel-size"},
           {"--dim 65536", "--dim"},
           {"--queue 0", "--queue"},
           {"--feature-size 4096x4096", "--feature-size 4096x4096 with --dim 512"},
           {"--distortion '1 2 3 nan 5'", "--distortion"},
       })
    expect_usage_error(map + args, mention);
  // The output directory is checked with every other output before the replay: a usage error.
  const CommandResult r = cli("map " + seq() + " -o " + out("missing/m.svdb"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;
  // A small voxel size is allowed, with a memory estimate.
  const CommandResult small = cli(map + "--voxel-size 0.05 --dim 8");
  EXPECT_EQ(small.exit_code, 0) << small.output;
  EXPECT_NE(small.output.find("MB of map memory per 100 m"), std::string::npos) << small.output;
}

TEST_F(CliOptionBounds, OtherCommandsRefuseOutOfRangeValues) {
  const std::string synth = "synth " + out("synth") + " ";
  expect_usage_error(synth + "--length 1e9", "--length");
  expect_usage_error(synth + "--camera-rate inf", "--camera-rate");
  expect_usage_error(synth + "--image-size 99999x40", "image size 99999x40");
  EXPECT_FALSE(fs::exists(tmp_.path / "synth"));
  // Before: --resolution inf wrote a 1 x 1 PNG.
  expect_usage_error("export " + out("m.svdb") + " --png " + out("m.png") + " --resolution inf", "--resolution");
  expect_usage_error("embed-text grass --simulated --threads 100000", "--threads");
  expect_usage_error("segment " + out("seq/pylon_camera_node/frame000000-1000_5.jpg") +
                         " --simulated --classes grass --out-dir " + out("seg") + " --max-image-pixels nan",
                     "--max-image-pixels");
  expect_usage_error("info", "map");  // a missing positional argument
}

TEST_F(CliOptionBounds, RuntimeFailuresExitOneNamingTheFile) {
  // A FIFO as times.txt: an error at once (before: `map` blocked forever).
  std::ofstream(tmp_.path / "seq" / "times.txt") << "1\n2\n3\n";
  fs::remove(tmp_.path / "seq" / "times.txt");
  ASSERT_EQ(::mkfifo((tmp_.path / "seq" / "times.txt").c_str(), 0600), 0);
  CommandResult r = cli("map " + seq() + " -o " + out("m.svdb"));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("times.txt"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("FIFO"), std::string::npos) << r.output;
  fs::remove(tmp_.path / "seq" / "times.txt");

  // Control characters from a file are escaped in the message.
  std::ofstream(tmp_.path / "seq" / "camera_info.txt") << "20 21 16 \x1b[2Jboom\n";
  r = cli("map " + seq() + " -o " + out("m.svdb"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("\\x1b[2Jboom"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find('\x1b'), std::string::npos) << r.output;
  testing::TinyRellis{}.write(tmp_.path / "seq");

  // An unreadable scan folder (before: exit 2, "unexpected failure"). Root reads everything, so
  // the command then runs as nobody.
  const fs::path scans = tmp_.path / "seq" / "os1_cloud_node_kitti_bin";
  ASSERT_EQ(::chmod(scans.c_str(), 0), 0);
  ::chmod(tmp_.path.c_str(), 0755);
  const std::string prefix = ::geteuid() == 0 ? "exec setpriv --reuid=65534 --regid=65534 --clear-groups " : "exec ";
  r = run_command(prefix + shell_quote(SLAMVDB_CLI_PATH) + " map " + seq() + " -o /tmp/slamvdb-never.svdb", 60.0);
  ::chmod(scans.c_str(), 0755);
  if (r.output.find("setpriv:") != std::string::npos) GTEST_SKIP() << r.output;
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("os1_cloud_node_kitti_bin"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Permission denied"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("unexpected"), std::string::npos) << r.output;
}

TEST_F(CliOptionBounds, QueryPointsFromAFifoAreAnErrorNotAHang) {
  ASSERT_EQ(cli("map " + seq() + " -o " + out("m.svdb") + " --dim 8").exit_code, 0);
  ASSERT_EQ(::mkfifo((tmp_.path / "points.csv").c_str(), 0600), 0);
  const CommandResult r = cli("query " + out("m.svdb") + " --at-csv " + out("points.csv"));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("points.csv"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("FIFO"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace slamvdb
