// The CLI conventions every command follows: --version, an unknown command named, exit codes
// (0 / 1 runtime / 2 usage), --quiet.
#include <gtest/gtest.h>

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
