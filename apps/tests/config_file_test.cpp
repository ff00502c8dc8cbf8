// `--config FILE.yaml` through the binary: what a file may hold (errors name the file), and the
// flags that a file used to set without effect doing what they do on the command line, end to end.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::cli {
namespace config_file_test {
namespace fs = std::filesystem;
using slamvdb::testing::run_command;
using slamvdb::testing::shell_quote;

const std::string kCli = shell_quote(SLAMVDB_CLI_PATH);

class ConfigFile : public ::testing::Test {
 protected:
  slamvdb::testing::TempDir tmp;
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(tmp.path / name) << text;
    return (tmp.path / name).string();
  }
  std::string path(const std::string& name) const { return shell_quote((tmp.path / name).string()); }
  // The configuration a map records, but for its own name (`output: ...`).
  static std::string config_of(const std::string& map) {
    const std::string config =
        nlohmann::json::parse(run_command(kCli + " info " + map + " --json").output)["config"].get<std::string>();
    EXPECT_EQ(config.rfind("output: ", 0), 0u) << config;
    return config.substr(config.find('\n'));
  }
};

TEST_F(ConfigFile, ProblemsAreUsageErrorsNamingTheFile) {
  const std::string seq = path("seq");
  const std::pair<std::string, std::string> cases[] = {
      {"length: 2\nlength: 3\n", "'length' is given twice (first on line 1)"},
      {"image_size: 64x40\nimage-size: 32x20\n", "'image-size' is given twice"},
      {"length: 2\n---\nseed: 3\n", "2 YAML documents"},
      {"? [a, b]\n: 1\n", "complex key"},
      {"length: {metres: 2}\n", "'length' is a mapping"},
      {"length:\n", "'length' has no value"},
      {"length: []\n", "'length' is an empty list"},
      {"force: maybe\n", "'force' is a flag: its value is true or false, not 'maybe'"},
      {"force: [true]\n", "'force' is a flag"},
      {"out_dir: x\n", "'out_dir' is a positional argument of `synth`"},
      {"lenght: 2\n", "line 1: 'lenght' is not an option of `synth`"},
      {"length: [2\n", "line 2"},
      {"- length\n", "expected a mapping"},
  };
  for (const auto& [text, expect] : cases) {
    const std::string file = write("c.yaml", text);
    const auto r = run_command(kCli + " synth " + seq + " --config " + shell_quote(file) + " 2>&1");
    EXPECT_EQ(r.exit_code, 2) << text << r.output;
    EXPECT_NE(r.output.find("config file " + file), std::string::npos) << text << r.output;
    EXPECT_NE(r.output.find(expect), std::string::npos) << text << r.output;
  }
  // A short and a long name of one option (`map -o`).
  const std::string twice = write("o.yaml", "o: a.svdb\noutput: b.svdb\n");
  const auto r = run_command(kCli + " map " + path("") + " --config " + shell_quote(twice) + " 2>&1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("'output' sets --output again (first as 'o' on line 1)"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "seq"));  // nothing ran
}

// The integer examples through the binary: exit code 2 naming the option (every integer
// option of every command: ConfigEquivalence.IntegerOptions...).
TEST_F(ConfigFile, IntegerOptionsDoNotWrap) {
  const std::string file = write("input.json", "{}\n");
  for (const std::string& args : {"query " + shell_quote(file) + " --text grass --top-k -3",
                                  "query " + shell_quote(file) + " --text grass --top-k 1e23",
                                  "map " + path("") + " -o " + path("m.svdb") + " --sim-seed -1"}) {
    const auto r = run_command(kCli + " " + args + " 2>&1");
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.output;
    EXPECT_NE(r.output.find(args.find("top-k") != std::string::npos ? "--top-k" : "--sim-seed"), std::string::npos)
        << r.output;
  }
}

// Config files are read like every other input: a FIFO does not block, a huge file is not read.
TEST_F(ConfigFile, OnlyRegularFilesOfAtMostOneMebibyte) {
  const std::string fifo = (tmp.path / "fifo.yaml").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto r = run_command(kCli + " synth " + path("seq") + " --config " + shell_quote(fifo) + " 2>&1", 30.0);
  ASSERT_FALSE(r.timed_out) << "--config on a FIFO blocks";
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("config file \"" + fifo + "\" is a FIFO"), std::string::npos) << r.output;
  const std::string big = write("big.yaml", "length: 2\n" + std::string(1100000, '#') + "\n");
  const auto b = run_command(kCli + " synth " + path("seq") + " --config " + shell_quote(big) + " 2>&1");
  EXPECT_EQ(b.exit_code, 2) << b.output;
  EXPECT_NE(b.output.find("config file \"" + big + "\" is 1100011 bytes"), std::string::npos) << b.output;
  for (const std::string& other : {tmp.path.string(), (tmp.path / "missing.yaml").string()}) {
    const auto o = run_command(kCli + " synth " + path("seq") + " --config " + shell_quote(other) + " 2>&1");
    EXPECT_EQ(o.exit_code, 2) << o.output;
    EXPECT_NE(o.output.find("config file \"" + other + "\""), std::string::npos) << o.output;
  }
  // --config before the command works too.
  const std::string good = write("good.yaml", "length: 2\nimage-size: 64x40\n");
  const auto g = run_command(kCli + " --config " + shell_quote(good) + " synth " + path("seq") + " 2>&1");
  EXPECT_EQ(g.exit_code, 0) << g.output;
}

// Each flag listed in the issue, from the command line and from a file: the same output, the same
// effect (against a run without it) and, for maps, the same recorded configuration.
TEST_F(ConfigFile, FlagsFromTheFileDoWhatTheyDoOnTheCommandLine) {
  const std::string seq = path("seq");
  ASSERT_EQ(run_command(kCli + " -q synth " + seq + " --length 3 --image-size 64x40 2>&1").exit_code, 0);
  const std::string small = " --voxel-size 0.5 --feature-size 24x16 --dim 8";
  const auto same_as_line = [&](const std::string& command, const std::string& flag, const std::string& out_line,
                                const std::string& out_file) {
    const std::string key = flag.substr(2);
    const auto line = run_command(kCli + " " + command + " " + flag + " -o " + out_line + " 2>&1");
    const auto file = run_command(kCli + " " + command + " -o " + out_file + " --config " +
                                  shell_quote(write(key + ".yaml", key + ": true\n")) + " 2>&1");
    EXPECT_EQ(line.exit_code, 0) << line.output;
    EXPECT_EQ(file.exit_code, 0) << file.output;
    return std::pair{line.output, file.output};
  };

  // map --realtime: the report says how it kept up with real time.
  auto [map_line, map_file] = same_as_line("map " + seq + small, "--realtime", path("rt1.svdb"), path("rt2.svdb"));
  EXPECT_NE(map_line.find("real time: kept up with"), std::string::npos) << map_line;
  EXPECT_NE(map_file.find("real time: kept up with"), std::string::npos) << map_file;
  EXPECT_EQ(config_of(path("rt1.svdb")), config_of(path("rt2.svdb")));
  EXPECT_NE(config_of(path("rt2.svdb")).find("realtime: true"), std::string::npos);

  // slam --no-loop-closure: no loop closer, so no loops line.
  auto [slam_line, slam_file] =
      same_as_line("slam " + seq + " --feature-size 24x16 --dim 8", "--no-loop-closure", path("s1.svdb"), path("s2.svdb"));
  const auto with_loops = run_command(kCli + " slam " + seq + " --feature-size 24x16 --dim 8 -o " + path("s0.svdb") + " 2>&1");
  EXPECT_NE(with_loops.output.find("  loops "), std::string::npos) << with_loops.output;
  EXPECT_EQ(slam_line.find("  loops "), std::string::npos) << slam_line;
  EXPECT_EQ(slam_file.find("  loops "), std::string::npos) << slam_file;
  EXPECT_EQ(config_of(path("s1.svdb")), config_of(path("s2.svdb")));

  // export --ascii: an ASCII PLY.
  const std::string map = path("rt1.svdb");
  same_as_line("export " + map, "--ascii", path("a1.ply"), path("a2.ply"));
  for (const char* ply : {"a1.ply", "a2.ply"}) {
    std::ifstream in(tmp.path / ply);
    std::string magic, format;
    std::getline(in, magic), std::getline(in, format);
    EXPECT_EQ(format, "format ascii 1.0") << ply;
  }

  // classify --no-void-rule and --ignore-model-id, with queries of another model id.
  QuerySet queries;
  queries.model_id = "another-model";
  queries.names = {"grass", "tree", "void"};
  queries.vectors = QueryMatrix::Random(3, 8);
  queries.void_classes = {2};
  save_query_set(tmp.path / "q.json", queries);
  const std::string classify = "classify " + map + " --queries " + path("q.json");
  const auto refused = run_command(kCli + " " + classify + " 2>&1");
  EXPECT_EQ(refused.exit_code, 1) << refused.output;  // another embedding space
  auto [ignore_line, ignore_file] = same_as_line(classify, "--ignore-model-id", path("i1.csv"), path("i2.csv"));
  EXPECT_NE(ignore_file.find("void -> second best on"), std::string::npos) << ignore_file;
  std::ofstream(tmp.path / "both.yaml") << "ignore-model-id: true\nno-void-rule: true\n";
  const auto no_void_line = run_command(kCli + " " + classify + " --ignore-model-id --no-void-rule -o " + path("v1.csv") + " 2>&1");
  const auto no_void_file = run_command(kCli + " " + classify + " -o " + path("v2.csv") + " --config " + path("both.yaml") + " 2>&1");
  for (const auto* r : {&no_void_line, &no_void_file}) {
    EXPECT_EQ(r->exit_code, 0) << r->output;
    EXPECT_NE(r->output.find("void -> second best off"), std::string::npos) << r->output;
  }
  const auto read = [&](const char* name) {
    std::ifstream in(tmp.path / name);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(read("i1.csv"), read("i2.csv"));
  EXPECT_EQ(read("v1.csv"), read("v2.csv"));
}

// The checks across options and the bounds of `map` hold for `slam` too, from the command line and
// from a file alike, before any work: a dimension or feature map too large, one scan too large for
// the memory.
TEST_F(ConfigFile, MappingCommandsShareTheirBoundsFromBothSources) {
  const std::string dataset = path("");
  struct Case {
    std::string args, yaml, expect;
  };
  const Case cases[] = {
      {"--dim 65536", "dim: 65536\n", "--dim"},
      {"--feature-size 4096x4096", "feature-size: 4096x4096\n", "--feature-size 4096x4096"},
      {"--voxel-size 0.01 --max-memory 4", "voxel-size: 0.01\nmax-memory: 4\n", "estimated to take"},
      {"--voxel-size 0.02 --max-memory 0.5", "voxel_size: 0.02\nmax_memory: 0.5\n", "more than the 0.5 GB of --max-memory"},
  };
  for (const char* command : {"map", "slam"}) {
    for (const Case& c : cases) {
      const std::string file = write("bounds.yaml", c.yaml);
      for (const std::string& given : {c.args, "--config " + shell_quote(file)}) {
        const auto r = run_command(kCli + " " + command + " " + dataset + " -o " + path("m.svdb") + " " + given + " 2>&1");
        EXPECT_EQ(r.exit_code, 2) << command << " " << given << ": " << r.output;
        EXPECT_NE(r.output.find(c.expect), std::string::npos) << command << " " << given << ": " << r.output;
      }
    }
  }
  EXPECT_FALSE(fs::exists(tmp.path / "m.svdb"));
}

}  // namespace config_file_test
}  // namespace slamvdb::cli
