// `slamvdb --help` lists every command in the order of the work (make data, map, localize, ask,
// look, share, evaluate, tools), one line each; each command's own --help keeps its full description.
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "slamvdb/testing/run_command.hpp"

namespace {

using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;

TEST(CliConventions, TopLevelHelpListsTheWorkflowOneLineEach) {
  const std::string cli = shell_quote(SLAMVDB_CLI_PATH);
  const auto help = run_command(cli + " --help 2>&1");
  ASSERT_EQ(help.exit_code, 0) << help.output;
  std::vector<std::string> workflow = {
      "synth", "convert", "demo",  // make data
      "map", "slam", "align", "merge",  // map
      "odometry",                // localize
      "query", "classify", "train-queries", "import-queries", "serve",  // ask
      "inspect", "info", "export",  // look
      "push", "pull", "add-shard",  // share
      "eval", "eval-images", "eval-trajectory",  // evaluate
      "tokenize", "embed-text", "segment"};      // tools
#if !SLAMVDB_WITH_TRAINING  // the demo trains query vectors: builds without Torch have no demo
  workflow.erase(std::find(workflow.begin(), workflow.end(), "demo"));
#endif
  std::vector<std::string> listed;
  std::istringstream lines(help.output);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("  ", 0) != 0 || line.size() < 3 || line[2] == '-' || line[2] == ' ') continue;  // options
    const std::string name = line.substr(2, line.find(' ', 2) - 2);
    listed.push_back(name);
    EXPECT_LE(line.size(), 80u) << "not one terminal line: " << line;
    EXPECT_GT(line.size(), name.size() + 10) << "no description: " << line;
  }
  EXPECT_EQ(listed, workflow) << help.output;
  EXPECT_EQ(help.output.find("Other:"), std::string::npos) << "a command the overview does not place";

  // Every command the program has is in the list (the unknown-command error names them all).
  const auto unknown = run_command(cli + " no-such-command 2>&1");
  const auto at = unknown.output.find("commands: ");
  ASSERT_NE(at, std::string::npos) << unknown.output;
  std::istringstream names(unknown.output.substr(at + 10, unknown.output.find(" (", at) - at - 10));
  for (std::string name; std::getline(names, name, ',');) {
    name.erase(0, name.find_first_not_of(' '));
    EXPECT_NE(std::find(listed.begin(), listed.end(), name), listed.end()) << name << " is not in --help";
  }
  // The long description stays with the command.
  const auto own = run_command(cli + " slam --help 2>&1");
  EXPECT_NE(own.output.find("merged where a loop shows two are the same place"), std::string::npos) << own.output;
}

}  // namespace
