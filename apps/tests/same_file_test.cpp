// An output that is the same file as an input is a usage error (exit 2) before any work, for every
// command: by device and inode, so a hard link or a symbolic link to the input counts whatever its
// name; and the input is left byte for byte. Two outputs of one run that are the same file too.
#include <gtest/gtest.h>

#include <functional>

#include "cli_files_fixture.hpp"

namespace slamvdb::testing {
namespace {

namespace fs = std::filesystem;

class SameFile : public CliFiles {};

struct SameFileCase {
  std::string command;
  fs::path input;
  std::string link;                                      // where the link to the input goes (in dir_)
  std::function<std::string(const fs::path& link)> args;  // the command line writing through the link
};

TEST_F(SameFile, AnOutputThatIsAnInputIsAUsageErrorAndTheInputStays) {
  const std::string map = q(CliFiles::map()), queries = q(CliFiles::queries()), seq = q(CliFiles::seq());
  std::ofstream(file("estimate.txt")) << slurp(CliFiles::seq() / "poses.txt");
  std::ofstream(file("points.csv")) << "x,y,z\n1,2,0\n";
  std::ofstream(file("ontology.yaml")) << "name: test\n";
  std::ofstream(file("model.pt")) << "not a model: never read";
  fs::create_directories(file("csv_dir"));
  std::ofstream(file("csv_dir") / "grass.csv") << "1,0,0\n";
  fs::copy_file(CliFiles::seq() / "pylon_camera_node_label_id" /
                    fs::directory_iterator(CliFiles::seq() / "pylon_camera_node_label_id")->path().filename(),
                file("labels.png"));
  const std::vector<SameFileCase> cases = {
      {"classify", CliFiles::queries(), "out.csv",
       [&](const fs::path& o) { return "classify " + map + " --queries " + queries + " -o " + q(o); }},
      {"export", CliFiles::map(), "out.ply", [&](const fs::path& o) { return "export " + map + " -o " + q(o); }},
      {"eval", CliFiles::map(), "out.md",
       [&](const fs::path& o) { return "eval " + map + " " + seq + " --queries " + queries + " -o " + q(o); }},
      {"eval-images", CliFiles::queries(), "out.md",
       [&](const fs::path& o) { return "eval-images " + seq + " --queries " + queries + " -o " + q(o); }},
      {"eval-trajectory", file("estimate.txt"), "out.json",
       [&](const fs::path& o) {
         return "eval-trajectory " + q(file("estimate.txt")) + " " + q(CliFiles::seq() / "poses.txt") + " -o " + q(o);
       }},
      {"import-queries", file("csv_dir") / "grass.csv", "out.json",
       [&](const fs::path& o) { return "import-queries " + q(file("csv_dir")) + " --model-id t -o " + q(o); }},
      {"map", file("estimate.txt"), "out.svdb",
       [&](const fs::path& o) { return "map " + seq + " --poses " + q(file("estimate.txt")) + " -o " + q(o) + kMapOptions; }},
      {"slam", CliFiles::map(), "out.svdb",
       [&](const fs::path& o) { return "slam " + seq + " --colour-basis " + map + " -o " + q(o) + kMapOptions; }},
      {"query", file("points.csv"), "out.csv",
       [&](const fs::path& o) { return "query " + map + " --at-csv " + q(file("points.csv")) + " -o " + q(o); }},
#ifdef SLAMVDB_WITH_TRAINING  // train-queries exists only in builds with Torch
      {"train-queries", file("ontology.yaml"), "out.json",
       [&](const fs::path& o) {
         return "train-queries " + seq + " --ontology " + q(file("ontology.yaml")) + " -o " + q(o) + kTrainOptions;
       }},
#endif
      {"embed-text", file("model.pt"), "out.npy",
       [&](const fs::path& o) { return "embed-text grass --model " + q(file("model.pt")) + " -o " + q(o); }},
      // A folder output: the file it would write there is the input image.
      {"segment", file("labels.png"), "segment_out/labels.png",
       [&](const fs::path& o) {
         return "segment " + q(file("labels.png")) + " --simulated --labels " + q(file("labels.png")) +
                " --classes a,b -o " + q(o.parent_path());
       }},
  };
  for (const SameFileCase& c : cases) {
    for (const bool hard : {true, false}) {
      SCOPED_TRACE(c.command + (hard ? " (hard link)" : " (symbolic link)"));
      const fs::path link = file(c.link);
      fs::remove(link);
      fs::create_directories(link.parent_path());
      if (hard) fs::create_hard_link(c.input, link);
      else fs::create_symlink(c.input, link);
      const std::string before = slurp(c.input);
      const auto r = run_cli(c.args(link));
      EXPECT_EQ(r.exit_code, 2) << r.output;
      EXPECT_NE(r.output.find("is the same file as"), std::string::npos) << r.output;
      EXPECT_EQ(slurp(c.input), before);
      EXPECT_EQ(hard ? fs::is_regular_file(fs::symlink_status(link)) : fs::is_symlink(link), true);
      fs::remove(link);
    }
  }
}

TEST_F(SameFile, TwoOutputsOfOneRunThatAreOneFileAreAUsageError) {
  // --grid g writes g.png (and g.yaml), which --png g.png writes too.
  const auto grid = run_cli("classify " + q(map()) + " --queries " + q(queries()) + " --png " + q(file("g.png")) +
                            " --grid " + q(file("g")));
  EXPECT_EQ(grid.exit_code, 2) << grid.output;
  EXPECT_NE(grid.output.find("are the same file"), std::string::npos) << grid.output;
  const auto odometry = run_cli("odometry " + q(seq()) + " -o " + q(file("a.txt")) + " --json " + q(file("a.txt")));
  EXPECT_EQ(odometry.exit_code, 2) << odometry.output;
  EXPECT_FALSE(fs::exists(file("a.txt")));
  // The config file is an input too.
  std::ofstream(file("classify.yaml")) << "robot-height: 1.5\n";
  const std::string config = slurp(file("classify.yaml"));
  const auto over_config = run_cli("classify " + q(map()) + " --queries " + q(queries()) + " --config " +
                                   q(file("classify.yaml")) + " -o " + q(file("classify.yaml")));
  EXPECT_EQ(over_config.exit_code, 2) << over_config.output;
  EXPECT_EQ(slurp(file("classify.yaml")), config);
}

}  // namespace
}  // namespace slamvdb::testing
