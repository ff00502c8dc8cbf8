// The CLI conventions every command follows: --version, an unknown command named, exit codes
// (0 / 1 runtime / 2 usage), --quiet.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace {

using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;
const std::string kCli = shell_quote(SLAMVDB_CLI_PATH);

TEST(CliConventions, VersionPrintsTheProjectVersionAndCommit) {
  const auto r = run_command(kCli + " --version 2>&1");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.output.rfind("slamvdb 0.", 0), 0u) << r.output;
  EXPECT_NE(r.output.find('('), std::string::npos) << r.output;
}

TEST(CliConventions, UnknownCommandIsNamedAndAUsageError) {
  const auto r = run_command(kCli + " bogus 2>&1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("unknown command 'bogus'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("map"), std::string::npos) << r.output;  // lists the commands
  EXPECT_EQ(run_command(kCli + " 2>&1").exit_code, 2);               // no command at all
}

TEST(CliConventions, ExitCodesAreZeroOneOrTwo) {
  EXPECT_EQ(run_command(kCli + " info --help > /dev/null").exit_code, 0);
  EXPECT_EQ(run_command(kCli + " info --no-such-option x.svdb 2>&1").exit_code, 2);
  EXPECT_EQ(run_command(kCli + " info 2>&1").exit_code, 2);                     // a missing argument
  EXPECT_EQ(run_command(kCli + " info /no/such/map.svdb 2>&1").exit_code, 1);   // a runtime error
  EXPECT_EQ(run_command(kCli + " --quiet --verbose info x 2>&1").exit_code, 2);
}

TEST(CliConventions, QuietPrintsNoProgressOrInfo) {
  slamvdb::testing::TempDir tmp;
  const std::string out = shell_quote((tmp.path / "seq").string());
  const auto quiet = run_command(kCli + " --quiet synth " + out + " --length 2 --image-size 64x40 2>&1 >/dev/null");
  EXPECT_EQ(quiet.exit_code, 0) << quiet.output;
  EXPECT_EQ(quiet.output.find("synth (simulated)"), std::string::npos) << quiet.output;
  const auto normal = run_command(kCli + " synth " + out + " --force --length 2 --image-size 64x40 2>&1 >/dev/null");
  EXPECT_NE(normal.output.find("frames/s"), std::string::npos) << normal.output;  // the rate, in its unit
}

}  // namespace

namespace {

TEST(CliConventions, ConfigFileSetsOptionsAndTheCommandLineWins) {
  slamvdb::testing::TempDir tmp;
  const auto write = [&](const std::string& name, const std::string& text) {
    const auto path = tmp.path / name;
    std::ofstream(path) << text;
    return shell_quote(path.string());
  };
  const std::string seq = shell_quote((tmp.path / "seq").string());
  const std::string good = write("synth.yaml", "length: 2\nimage_size: 64x40\nseed: 3\n");
  const auto r = run_command(kCli + " synth " + seq + " --config " + good + " 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("64x40"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("path length 2."), std::string::npos) << r.output;
  const auto wins = run_command(kCli + " synth " + seq + " --force --length 3 --config " + good + " 2>&1");
  EXPECT_NE(wins.output.find("path length 3."), std::string::npos) << wins.output;
  const auto typo = run_command(kCli + " synth " + seq + " --config " + write("typo.yaml", "lenght: 2\n") + " 2>&1");
  EXPECT_EQ(typo.exit_code, 2);
  EXPECT_NE(typo.output.find("'lenght' is not an option of `synth`"), std::string::npos) << typo.output;
  const auto bad = run_command(kCli + " synth " + seq + " --config " + write("bad.yaml", "length: nan\n") + " 2>&1");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  const auto broken = run_command(kCli + " synth " + seq + " --config " + write("broken.yaml", "length: [2\n") + " 2>&1");
  EXPECT_EQ(broken.exit_code, 2) << broken.output;

  // A map records the options it was made with, as a config file `map --config` reads back.
  const std::string map = shell_quote((tmp.path / "m.svdb").string());
  const auto mapped = run_command(kCli + " map " + seq + " -o " + map + " --config " +
                                  write("map.yaml", "voxel-size: 0.5\nfeature-size: 24x16\ndim: 8\n"
                                                    "sim-feature-precision: fp16\n") +
                                  " 2>&1");
  ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
  const auto info = run_command(kCli + " info " + map + " --json");
  const auto config = nlohmann::json::parse(info.output)["config"].get<std::string>();
  EXPECT_NE(config.find("voxel-size: 0.5"), std::string::npos) << config;
  EXPECT_NE(config.find("sim-feature-precision: fp16"), std::string::npos) << config;
  EXPECT_NE(config.find("submap-length: 50"), std::string::npos) << config;  // defaults too
  std::ofstream(tmp.path / "again.yaml") << config;
  const auto again = run_command(kCli + " map " + seq + " --config " + shell_quote((tmp.path / "again.yaml").string()) +
                                 " -o " + shell_quote((tmp.path / "m2.svdb").string()) + " 2>&1");
  EXPECT_EQ(again.exit_code, 0) << again.output;
  const auto fp8 = run_command(kCli + " map " + seq + " -o " + map + " --sim-feature-precision fp8 2>&1");
  EXPECT_EQ(fp8.exit_code, 2) << fp8.output;  // a usage error, before any work
}

}  // namespace
