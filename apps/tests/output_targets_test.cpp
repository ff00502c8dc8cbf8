// Every command's outputs go through the one writer (core/output_file.hpp): a device or FIFO at
// the output path is written through and stays what it is (a full one is exit 1 naming the file
// and "No space left on device"), a symbolic link stays a link, what cannot hold the output is a
// usage error before any work; and two runs never write one map file at once.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <chrono>
#include <functional>
#include <future>
#include <thread>

#include "cli_files_fixture.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb::testing {
namespace {

namespace fs = std::filesystem;

class OutputTargets : public CliFiles {};

struct CommandCase {
  std::string name, extension;
  std::function<std::string(const std::string& output)> args;
};

// The drive odometry and slam write from. Under the sanitizers (test_scale.hpp) a 10 m part of the
// suite's drive (22 scans, not 62): those two commands register every scan, 0.3-0.6 s each under
// ASan, and each runs twice here (full and null device), which was most of this test's 141 s. What
// the test proves, the writer's path through a device, does not depend on the number of scans;
// their registration runs under ASan on the whole drive in SlamCommand and OdometryCommand.
fs::path output_targets_registration_drive() {
  if (!sanitizer_test_scale()) return CliFiles::seq();
  const fs::path drive = CliFiles::file("seq_10m");
  if (!fs::exists(drive)) {
    synth::SynthConfig config;  // the fixture's drive, shorter
    config.seed = 3;
    config.length_m = 10.0;
    config.image_width = 64;
    config.image_height = 40;
    config.lidar.columns = 512;
    synth::write_synthetic_sequence(config, drive, true);
  }
  return drive;
}

std::vector<CommandCase> commands_with_outputs() {
  const auto q = [](const fs::path& p) { return quote_path(p); };
  const std::string map = q(CliFiles::file("m.svdb")), queries = q(CliFiles::file("q.json")),
                    seq = q(CliFiles::file("seq")), poses = q(CliFiles::file("seq") / "poses.txt"),
                    drive = q(output_targets_registration_drive());
  fs::create_directories(CliFiles::file("csv_queries"));
  std::ofstream(CliFiles::file("csv_queries") / "grass.csv") << "1,0,0\n";
  std::ofstream(CliFiles::file("csv_queries") / "tree.csv") << "0,1,0\n";
  return {
      {"classify", ".csv", [=](const std::string& o) { return "classify " + map + " --queries " + queries + " -o " + o; }},
      {"export", ".ply", [=](const std::string& o) { return "export " + map + " -o " + o; }},
#ifdef SLAMVDB_WITH_TRAINING  // train-queries exists only in builds with Torch
      {"train-queries", ".json",
       [=](const std::string& o) { return "train-queries " + seq + " -o " + o + CliFiles::kTrainOptions; }},
#endif
      {"map", ".svdb", [=](const std::string& o) { return "map " + seq + " -o " + o + CliFiles::kMapOptions; }},
      {"slam", ".svdb", [=](const std::string& o) { return "slam " + drive + " -o " + o + CliFiles::kMapOptions; }},
      {"odometry", ".txt", [=](const std::string& o) { return "odometry " + drive + " -o " + o; }},
      {"eval", ".md", [=](const std::string& o) { return "eval " + map + " " + seq + " --queries " + queries + " -o " + o; }},
      {"eval-images", ".json",
       [=](const std::string& o) {
         return "eval-images " + seq + " --queries " + queries + " --json " + o + CliFiles::kMapOptions;
       }},
      {"eval-trajectory", ".json", [=](const std::string& o) { return "eval-trajectory " + poses + " " + poses + " -o " + o; }},
      {"query", ".csv", [=](const std::string& o) { return "query " + map + " --text grass -o " + o + " --sim-seed 1"; }},
      {"import-queries", ".json",
       [=](const std::string& o) {
         return "import-queries " + q(CliFiles::file("csv_queries")) + " --model-id test -o " + o;
       }},
  };
}

TEST_F(OutputTargets, DevicesAreWrittenThroughAndAFullOneIsAnErrorWithTheReason) {
  for (const CommandCase& c : commands_with_outputs()) {
    SCOPED_TRACE(c.name);
    const fs::path full = file("full_" + c.name + c.extension), null = file("null_" + c.name + c.extension);
    if (!make_char_device(full, 7) || !make_char_device(null, 3))
      GTEST_SKIP() << "cannot create device nodes here (mknod: " << std::strerror(errno) << "; needs root)";
    const auto to_full = run_cli(c.args(q(full)));
    EXPECT_EQ(to_full.exit_code, 1) << to_full.output;
    EXPECT_NE(to_full.output.find("No space left on device"), std::string::npos) << to_full.output;
    EXPECT_NE(to_full.output.find(full.string()), std::string::npos) << to_full.output;
    EXPECT_TRUE(is_char_device(full));
    const auto to_null = run_cli(c.args(q(null)));
    EXPECT_EQ(to_null.exit_code, 0) << to_null.output;
    EXPECT_TRUE(is_char_device(null));
  }
}

// What a FIFO's reader gets is the file the command writes to a regular path: the map file too
// (written to a temporary file while mapping, copied through at the end).
TEST_F(OutputTargets, AFifoGetsTheWholeOutput) {
  const auto read_all = [](const fs::path& fifo) {
    return std::async(std::launch::async, [fifo] { return slurp(fifo); });
  };
  const fs::path fifo = file("pipe.ply"), svdb_fifo = file("pipe.svdb");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  ASSERT_EQ(::mkfifo(svdb_fifo.c_str(), 0600), 0);
  auto ply = read_all(fifo);
  const auto exported = run_cli("export " + q(map()) + " -o " + q(fifo));
  ASSERT_EQ(exported.exit_code, 0) << exported.output;
  ASSERT_EQ(run_cli("export " + q(map()) + " -o " + q(file("file.ply"))).exit_code, 0);
  EXPECT_EQ(ply.get(), slurp(file("file.ply")));

  auto svdb = read_all(svdb_fifo);
  const auto mapped = run_cli("map " + q(seq()) + " -o " + q(svdb_fifo) + kMapOptions + " --quiet");
  ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
  std::ofstream(file("from_fifo.svdb"), std::ios::binary) << svdb.get();
  const auto info = run_cli("info --check " + q(file("from_fifo.svdb")));
  EXPECT_EQ(info.exit_code, 0) << info.output;
  struct stat st {};
  ASSERT_EQ(::lstat(svdb_fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

TEST_F(OutputTargets, StandardOutputAndSymbolicLinks) {
  const auto to_stdout = run_cli("odometry " + q(seq()) + " -o /dev/stdout");
  EXPECT_EQ(to_stdout.exit_code, 0) << to_stdout.output;
  EXPECT_NE(to_stdout.output.find("1.000000000e+00 0.000000000e+00"), std::string::npos) << to_stdout.output;
  // Standard output itself is checked too: a full device behind it is exit 1 with the reason.
  if (fs::exists("/dev/full")) {
    const auto full = run_cli("query " + q(map()) + " --at 1,2,0 > /dev/full");
    EXPECT_EQ(full.exit_code, 1) << full.output;
    EXPECT_NE(full.output.find("cannot write standard output: No space left on device"), std::string::npos)
        << full.output;
  }

  std::ofstream(file("real.csv")) << "old";
  fs::create_symlink("real.csv", file("latest.csv"));
  const auto linked = run_cli("classify " + q(map()) + " --queries " + q(queries()) + " -o " + q(file("latest.csv")));
  EXPECT_EQ(linked.exit_code, 0) << linked.output;
  EXPECT_TRUE(fs::is_symlink(file("latest.csv")));
  EXPECT_EQ(slurp(file("real.csv")).rfind("x,y,z,class", 0), 0u);
}

TEST_F(OutputTargets, WhatCannotHoldTheOutputIsAUsageErrorBeforeAnyWork) {
  if (!make_char_device(file("null_picture.png"), 3)) GTEST_SKIP() << "cannot create device nodes here (needs root)";
  // A picture and its map_server .yaml cannot both go to one device.
  const auto picture = run_cli("classify " + q(map()) + " --queries " + q(queries()) + " --png " +
                               q(file("null_picture.png")));
  EXPECT_EQ(picture.exit_code, 2) << picture.output;
  EXPECT_NE(picture.output.find("a device or FIFO takes one"), std::string::npos) << picture.output;
  const fs::path block = file("block.ply");
  ASSERT_EQ(::mknod(block.c_str(), S_IFBLK | 0600, makedev(7, 0)), 0);
  const auto to_block = run_cli("export " + q(map()) + " -o " + q(block));
  EXPECT_EQ(to_block.exit_code, 2) << to_block.output;
  EXPECT_NE(to_block.output.find("a block device"), std::string::npos) << to_block.output;
  EXPECT_TRUE(fs::is_block_file(block));
  const auto to_dir = run_cli("odometry " + q(seq()) + " -o " + q(seq()));
  EXPECT_EQ(to_dir.exit_code, 2) << to_dir.output;
  EXPECT_NE(to_dir.output.find("a directory"), std::string::npos) << to_dir.output;
}

// Two runs writing one map file: the second fails at once naming the first (its PID and command);
// once the first is killed (-9), a third run is not blocked.
TEST_F(OutputTargets, OneMapRunAtATimePerOutput) {
  const fs::path out = file("locked.svdb"), lock = file(".locked.svdb.lock");
  const std::string args = "map " + q(seq()) + " -o " + q(out) + kMapOptions + " --quiet";
  ChildProcess first(shell_quote(SLAMVDB_CLI_PATH) + " " + args + " --realtime", file("first.log"));
  ASSERT_TRUE(first.started());
  std::string holder;
  for (int i = 0; i < 400 && holder.empty() && first.running(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
    holder = slurp(lock);
  }
  ASSERT_FALSE(holder.empty()) << slurp(file("first.log"));
  holder = holder.substr(0, holder.find('\n'));
  EXPECT_EQ(holder.rfind("PID ", 0), 0u) << holder;
  const auto start = std::chrono::steady_clock::now();
  const auto second = run_cli(args);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(second.exit_code, 1) << second.output;
  EXPECT_NE(second.output.find("is being written by another slamvdb run (" + holder), std::string::npos)
      << second.output;
  EXPECT_NE(second.output.find(out.string()), std::string::npos) << second.output;
  EXPECT_LT(seconds, 3.0);
  EXPECT_TRUE(first.running()) << "the first run must still be mapping (--realtime: 6 s)";
  first.kill_now();
  const auto third = run_cli(args);
  EXPECT_EQ(third.exit_code, 0) << third.output;
  EXPECT_EQ(run_cli("info " + q(out)).exit_code, 0);
  EXPECT_FALSE(fs::exists(lock));
}

}  // namespace
}  // namespace slamvdb::testing
