// `--config` gives exactly the command line's behaviour: every option of every command, enumerated
// from the same CommandLine the binary builds (a new option is covered without touching this
// file), is parsed once from the command line and once from a config file, and both must end the
// same way (the same error, or success), record the same configuration (what `map` and `slam` store
// in the map file), hold the same values and have converted them (run their callbacks). Commands do
// not run (CommandLine::set_check_only): only parsing and the option checks happen.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "command_line.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::cli {
namespace config_equivalence_test {
namespace fs = std::filesystem;

// How one parse ended.
struct ParseOutcome {
  std::string error;     // empty: parsed and checked
  std::string recorded;  // effective_config of the command
  std::map<std::string, std::vector<std::string>> values;
  std::set<std::string> unconverted;  // options holding text their callback never converted
};

// args: the command, then its arguments. The parser holds that command only (the tests below
// enumerate the commands and options of a whole CommandLine): building every command for each of
// the ~4000 parses was three quarters of their time.
ParseOutcome parse_only(const std::vector<std::string>& args) {
  CommandLine cli(args.front());
  cli.set_check_only(true);
  std::vector<const char*> argv{"slamvdb"};
  for (const std::string& a : args) argv.push_back(a.c_str());
  ParseOutcome out;
  try {
    cli.parse(static_cast<int>(argv.size()), argv.data());
    out.error = "the command ran";
  } catch (const CLI::Success&) {  // checked, not run
  } catch (const CLI::ParseError& e) {
    out.error = e.get_name() + ": " + e.what();
  } catch (const std::exception& e) {
    out.error = std::string("runtime error: ") + e.what();
  }
  const auto parsed = cli.get_subcommands();
  if (parsed.empty()) return out;
  out.recorded = effective_config(*parsed.front());
  for (const CLI::Option* o : parsed.front()->get_options()) {
    if (o->count() == 0) continue;
    out.values[o->get_name()] = o->results();
    if (!o->get_callback_run()) out.unconverted.insert(o->get_name());
  }
  return out;
}

// Errors that quote the machine's free disk space or memory, which change between two runs.
std::string machine_state_masked(const std::string& error) {
  static const std::regex kState(R"([0-9.]+ (MB|GB) (free|available))");
  return std::regex_replace(error, kState, "N $1 $2");
}

// One way to give an option: its values (one, or several for a repeatable option) and other
// arguments it needs to succeed (given on the command line in both runs).
struct Sample {
  std::vector<std::string> values;
  std::vector<std::string> companions;
};

class ConfigEquivalence : public ::testing::Test {
 protected:
  slamvdb::testing::TempDir tmp;
  fs::path dir = tmp.path / "dataset", file = tmp.path / "input.json", basis_map = tmp.path / "basis.svdb";

  void SetUp() override {
    fs::create_directories(dir);
    std::ofstream(file) << "{}\n";
    // An empty 512-d map with a colour basis, for --colour-basis.
    MapInfo info;
    info.model_id = "model";
    ColourBasis basis;
    basis.mean = Eigen::VectorXf::Zero(512);
    basis.components = Eigen::Matrix<float, 3, Eigen::Dynamic>::Identity(3, 512);
    info.colour_basis = basis;
    save_map(basis_map, SemanticMap(MapParams{}, info));
  }

  static std::string type_of(const CLI::Option* o) { return o->get_type_name(); }
  static bool is_flag(const CLI::Option* o) { return o->get_items_expected_max() == 0; }
  static std::string key_of(const CLI::Option* o) { return o->get_lnames().front(); }

  // A value for an argument every run of `cmd` needs (positional or required option).
  std::string needed_value(const std::string& cmd, const CLI::Option* o) const {
    const std::string type = type_of(o);
    if (type.find(":DIR") != std::string::npos) return dir.string();
    if (type.find(":FILE") != std::string::npos) return file.string();
    const std::string name = o->get_name();
    if (name == "--classes") return "grass,tree";
    if (name == "--model-id") return "model";
    if (name == "text") return "tall grass";
    if (name == "--output" || name == "out_dir") {
      if (cmd == "map") return file.string();  // an existing file, so that --resume can be tried
      if (cmd == "slam") return (tmp.path / "out.svdb").string();
      return (tmp.path / (cmd == "segment" || cmd == "synth" ? "out" : "out.json")).string();
    }
    return file.string();  // a map or input file that exists
  }

  // The arguments every run of `cmd` has besides the option tried (which is left out of them).
  std::vector<std::string> base_args(CLI::App* cmd, const CLI::Option* tried) const {
    std::vector<std::string> args{cmd->get_name()};
    // query, classify and serve read a map file or, with --db, a fleet: the file unless a fleet
    // option is tried.
    const bool fleet_tried =
        (cmd->get_name() == "query" || cmd->get_name() == "classify" || cmd->get_name() == "serve") &&
        (tried->get_name() == "--db" || tried->get_name() == "--session");
    for (const CLI::Option* o : cmd->get_options()) {
      const bool map_file = o->get_positional() && o->get_name() == "map" && !fleet_tried;
      if (o == tried || (!o->get_required() && !map_file)) continue;
      if (o->get_positional())  // as many values as it needs (merge: two maps or more)
        for (int i = 0; i < std::max(1, o->get_items_expected_min()); ++i) args.push_back(needed_value(cmd->get_name(), o));
      else args.push_back(o->get_name() + "=" + needed_value(cmd->get_name(), o));
    }
    if (cmd->get_name() == "export" && tried->get_name() != "--output") args.push_back("--output=" + (tmp.path / "m.ply").string());
    return args;
  }

  // The values tried for an option: both values of a flag; the ends, the middle and a value outside
  // a numeric range; every member of a set; a file and a missing one for path options; the default;
  // and values of options with a syntax of their own.
  std::vector<Sample> samples_of(const std::string& cmd, const CLI::Option* o) const {
    if (is_flag(o)) {
      Sample on{{"true"}, {}}, off{{"false"}, {}};
      if (cmd == "map" && o->get_name() == "--no-loop-closure") on.companions = off.companions = {"--odometry"};
      if (cmd == "segment" && o->get_name() == "--simulated")
        on.companions = off.companions = {"--labels=" + file.string()};
      return {on, off};
    }
    std::vector<Sample> samples;
    const auto one = [&](std::string v, std::vector<std::string> companions = {}) {
      samples.push_back({{std::move(v)}, std::move(companions)});
    };
    const std::string type = type_of(o), name = o->get_name();
    static const std::regex kRange(R"(in ([\[(])(-?[0-9.e+]+), (-?[0-9.e+]+)\])");
    std::smatch m;
    if (std::regex_search(type, m, kRange)) {
      const double lo = std::stod(m[2]), hi = std::stod(m[3]);
      const bool integer = type.rfind("INT", 0) == 0 || type.rfind("UINT", 0) == 0;
      const auto text = [&](double v) { return integer ? fmt::format("{}", static_cast<long long>(v)) : fmt::format("{}", v); };
      if (m[1] == "[") one(std::string(m[2]));
      one(std::string(m[3]));
      one(text(integer ? std::floor((lo + hi) / 2) : (lo + hi) / 2));
      one(integer ? "1.5" : "nan");
      if (lo > -1e18) one(text(lo - 1));
    }
    static const std::regex kSet(R"(\{([^{}>]+)\})");
    if (std::regex_search(type, m, kSet)) {
      std::stringstream members(m[1].str());
      for (std::string v; std::getline(members, v, ',');) one(v);
    }
    if (type.find(":FILE") != std::string::npos || type.find(":DIR") != std::string::npos) {
      one(type.find(":DIR") != std::string::npos ? dir.string() : file.string());
      one((tmp.path / "missing").string());
    }
    if (!o->get_default_str().empty()) one(o->get_default_str());
    static const std::map<std::string, std::vector<std::string>> kSyntax = {
        {"--feature-size", {"24x16", "4096x4096", "0x3"}},
        {"--image-size", {"64x40", "64"}},
        {"--distortion", {"-0.1 0.01 0 0.002 0", "1 2 3"}},
        {"--images", {"0:3", "3:0"}},
        {"--part", {"0.5:1"}},
        {"--at", {"1,2,3"}},
        {"--initial", {"1,2,0,30", "1,2,3"}},
        {"--bbox", {"0,0,0,1,1,1", "0,0,2,1,1,1"}},
        {"--near", {"1,2", "1,2,3,4"}},
        {"--text", {"grass"}},
        {"--not", {"tree"}},
        {"--class", {"rough"}},
        {"--not-class", {"smooth"}},
        {"--cost", {"rough=40", "rough=400"}},
        {"--ontology", {"rellis3d-coarse"}},
        {"--model-id", {"model"}},
        {"--classes", {"grass,tree"}},
        {"--features-model-id", {"precomputed:x"}},
    };
    if (const auto it = kSyntax.find(name); it != kSyntax.end())
      for (const std::string& v : it->second) one(v);
    if (name == "--colour-basis") one(basis_map.string());
    // Output paths (and other free text): a name in an existing folder, and one in a missing folder.
    if (samples.empty()) {
      for (const char* ext : {".ply", ".png", ".csv", ".json", ".svdb", ".txt", ".md"})
        one((tmp.path / (std::string("out") + ext)).string());
      one((tmp.path / "no" / "such" / "out.json").string());
    }
    if (cmd == "query" && name == "--class") samples.back().companions = {"--queries=" + file.string()};
    if (name == "--model" && (cmd == "slam" || cmd == "train-queries" || cmd == "eval" || cmd == "eval-images"))
      for (Sample& s : samples) s.companions = {"--features=model"};
    if (name == "--features-model-id") samples.back().companions = {"--features=precomputed"};
    if (name == "--labels")
      for (Sample& s : samples) s.companions = {"--simulated"};
    if (cmd == "synth" && (name == "--compression" || name == "--chunk-size"))
      for (Sample& s : samples) s.companions = {"--format=mcap"};
    if ((cmd == "query" || cmd == "classify") && (name == "--near" || name == "--radius"))  // the two go together
      for (Sample& s : samples) s.companions = {name == "--near" ? "--radius=2" : "--near=1,2"};
    if ((cmd == "query" || cmd == "classify") && (name == "--db" || name == "--session"))  // a fleet needs a region
      for (Sample& s : samples)
        s.companions = name == "--db" ? std::vector<std::string>{"--bbox=0,0,0,1,1,1"}
                                      : std::vector<std::string>{"--db=postgresql:///fleet", "--bbox=0,0,0,1,1,1"};
    if (cmd == "serve" && name == "--session")  // a fleet's sessions (serve needs no region)
      for (Sample& s : samples) s.companions = {"--db=postgresql:///fleet"};
    if (cmd == "serve" && (name == "--tls-cert" || name == "--tls-key"))  // the two go together
      for (Sample& s : samples) s.companions = {(name == "--tls-cert" ? "--tls-key=" : "--tls-cert=") + file.string()};
    if (o->get_expected_max() > 1 && !samples.empty())  // a repeatable option: two values at once
      samples.push_back({{samples.front().values.front(), samples.back().values.front()}, {}});
    if (cmd == "serve" && name == "--cost")  // costs of the query set's classes
      for (Sample& s : samples) s.companions = {"--queries=" + file.string()};
    return samples;
  }

  // The option given on the command line (--name=value, once per value) and in a config file.
  ParseOutcome from_command_line(CLI::App* cmd, const CLI::Option* o, const Sample& s) const {
    std::vector<std::string> args = base_args(cmd, o);
    for (const std::string& v : s.values) args.push_back(is_flag(o) && v == "true" ? o->get_name() : o->get_name() + "=" + v);
    args.insert(args.end(), s.companions.begin(), s.companions.end());
    return parse_only(args);
  }
  ParseOutcome from_config(CLI::App* cmd, const CLI::Option* o, const Sample& s) const {
    YAML::Emitter yaml;
    yaml << YAML::BeginMap << YAML::Key << key_of(o) << YAML::Value;
    if (s.values.size() == 1) yaml << s.values.front();
    else yaml << YAML::Flow << s.values;
    yaml << YAML::EndMap;
    const fs::path config = tmp.path / "config.yaml";
    std::ofstream(config) << yaml.c_str() << "\n";
    std::vector<std::string> args = base_args(cmd, o);
    args.push_back("--config=" + config.string());
    args.insert(args.end(), s.companions.begin(), s.companions.end());
    return parse_only(args);
  }
};

TEST_F(ConfigEquivalence, EveryOptionOfEveryCommandBehavesTheSameFromTheFile) {
  CommandLine cli;
  std::size_t options = 0, runs = 0;
  for (CLI::App* cmd : cli.get_subcommands({})) {
    for (const CLI::Option* o : cmd->get_options()) {
      if (o->get_lnames().empty() || !o->get_configurable()) continue;  // positional arguments, --help
      ++options;
      bool some_succeeded = false;
      for (const Sample& s : samples_of(cmd->get_name(), o)) {
        const ParseOutcome line = from_command_line(cmd, o, s), file = from_config(cmd, o, s);
        const std::string what = cmd->get_name() + " " + o->get_name() + " = " + CLI::detail::join(s.values, " | ");
        EXPECT_EQ(machine_state_masked(line.error), machine_state_masked(file.error)) << what;
        EXPECT_EQ(line.recorded, file.recorded) << what;
        EXPECT_EQ(line.values, file.values) << what;
        if (line.error.empty()) {
          EXPECT_TRUE(line.unconverted.empty()) << what;
          EXPECT_TRUE(file.unconverted.empty()) << what << ": " << CLI::detail::join(file.unconverted);
          EXPECT_EQ(file.values.count(o->get_name()), 1u) << what;  // the file's value is held
          some_succeeded = true;
        }
        ++runs;
      }
      EXPECT_TRUE(some_succeeded) << cmd->get_name() << " " << o->get_name()
                                  << ": no sample value parses; give it one in samples_of";
    }
  }
  EXPECT_GT(options, 150u);  // every command's options were found
  RecordProperty("runs", static_cast<int>(runs));
}

// An option on the command line wins over the file; the file fills in the others; values from
// the file are checked with the command line's (the checks across options see both).
TEST_F(ConfigEquivalence, CommandLineWinsAndChecksSeeBothSources) {
  const fs::path config = tmp.path / "map.yaml";
  std::ofstream(config) << "voxel-size: 0.5\ndim: 8\nfeature-size: 24x16\nrealtime: true\n";
  const ParseOutcome both = parse_only({"map", dir.string(), "-o", file.string(), "--voxel-size=0.25",
                                        "--config=" + config.string()});
  ASSERT_EQ(both.error, "");
  EXPECT_EQ(both.values.at("--voxel-size"), std::vector<std::string>{"0.25"});
  EXPECT_EQ(both.values.at("--dim"), std::vector<std::string>{"8"});
  EXPECT_EQ(both.values.at("--realtime"), std::vector<std::string>{"true"});
  // feature-size from the file, dim from the command line: the feature map bound sees both.
  std::ofstream(config) << "feature-size: 4096x4096\n";
  const ParseOutcome big = parse_only({"map", dir.string(), "-o", file.string(), "--dim=512", "--config=" + config.string()});
  EXPECT_NE(big.error.find("--feature-size 4096x4096 with --dim 512"), std::string::npos) << big.error;
  // A required option may come from the file.
  std::ofstream(config) << "output: " << file.string() << "\n";
  EXPECT_EQ(parse_only({"map", dir.string(), "--config=" + config.string()}).error, "");
}

// Every integer option of every command refuses what CLI11's strtoull/strtoll would wrap, saturate
// or cut: a negative value below its range (`--sim-seed -1` was 18446744073709551615), an overflow,
// a fraction and an exponent (`--top-k 1e23` returned every voxel). A usage error naming the option,
// from the command line and from a file.
TEST_F(ConfigEquivalence, IntegerOptionsRefuseNegativeOverflowingFractionalAndExponentValues) {
  CommandLine cli;
  std::size_t integers = 0;
  static const std::regex kRange(R"(in \[(-?[0-9]+), ([0-9]+)\])");
  for (CLI::App* cmd : cli.get_subcommands({})) {
    for (CLI::Option* o : cmd->get_options()) {
      const std::string type = type_of(o);
      if (type.rfind("INT", 0) != 0 && type.rfind("UINT", 0) != 0) continue;
      ++integers;
      const std::string what = cmd->get_name() + " " + o->get_name();
      std::smatch m;
      ASSERT_TRUE(std::regex_search(type, m, kRange)) << what << ": " << type;
      const long long lo = std::stoll(m[1]);
      EXPECT_GE(lo, -1) << what << " declares no lower bound";
      if (lo < -1) continue;
      ASSERT_NO_THROW(o->get_validator("INTEGER_RANGE")) << what;
      for (const std::string& bad : {std::to_string(lo - 1), std::string("99999999999999999999"), std::string("1.5"),
                                     std::string("1e3"), std::string("1e23"), std::string("0x10")}) {
        for (const ParseOutcome& r : {from_command_line(cmd, o, Sample{{bad}, {}}), from_config(cmd, o, Sample{{bad}, {}})}) {
          EXPECT_EQ(r.error.rfind("ValidationError: " + o->get_name() + ": ", 0), 0u) << what << " " << bad << ": " << r.error;
          EXPECT_NE(r.error.find(bad), std::string::npos) << what << " " << bad << ": " << r.error;
        }
      }
    }
  }
  EXPECT_GT(integers, 20u);
}

}  // namespace config_equivalence_test
}  // namespace slamvdb::cli
