#pragma once
// The `slamvdb` command line: the root options (--quiet, --verbose, --config), every registered
// command, and the order in which option values are read and checked, which is what makes a value
// from --config behave exactly like the same value on the command line:
//   1. CLI11 reads the arguments, the root's and the command's: each option keeps its raw text.
//   2. --config (a root option, so its callback runs before any of the command's) adds the file's
//      values to the options the command line left empty, as raw text too (yaml_config.hpp).
//   3. CLI11 converts and validates every option of the command (flags included) and checks the
//      required ones, whichever source their text came from.
//   4. The root's parse-complete callback applies --quiet / --verbose and runs the command's
//      checks that involve several options (add_option_checks).
//   5. The command's callback does the work.
// Commands therefore never use parse_complete_callback (it would run between 1 and 2).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "command_overview.hpp"
#include "command_registry.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "yaml_config.hpp"

namespace slamvdb::cli {

class CommandLine : public CLI::App, public OptionCheckRegistry {
 public:
  CommandLine() : CommandLine(std::string()) {}

  // The root options and the one command named `only` (every command when empty): the parser of a
  // test of one command's option layer, which parses thousands of times. Building every option of
  // every command was most of such a parse: ConfigEquivalence.* (about 4000 parses) took 93 s of
  // the ASan run, and 10.8 CPU-s in Release, 3.8 with one command per parse.
  explicit CommandLine(const std::string& only)
      : CLI::App("slamvdb: open-vocabulary semantic voxel maps from LiDAR and camera") {
    require_subcommand(1);
    formatter(std::make_shared<CommandOverviewFormatter>());  // --help: the commands in workflow order
    fallthrough();  // root options (--quiet, --config, ...) are accepted after the command too
    set_help_all_flag("--help-all", "Show help for every subcommand");
    add_flag("-q,--quiet", quiet_, "Print only warnings and errors (no progress bars)");
    add_flag("-v,--verbose", verbose_, "Print debug messages too");
    add_option_function<std::string>(
        "--config", [this](const std::string& file) { apply_config(file); },
        "Read the command's options from this YAML file: long option names as keys (`voxel-size: 0.2`), lists as "
        "YAML lists, flags as true or false; the command line wins. Values from the file are checked exactly as on "
        "the command line")
        ->type_name("FILE.yaml")
        ->configurable(false);
    const std::vector<CommandFactory>& factories = command_factories();
    for (std::size_t i = 0; i < factories.size(); ++i) {
      if (!only.empty() && command_names().at(i) != only) continue;
      const std::size_t before = get_subcommands({}).size();
      factories[i](*this);
      if (get_subcommands({}).size() != before + 1) throw std::logic_error("a command factory adds one command");
      factory_commands_.push_back(get_subcommands({}).back()->get_name());
    }
    if (!only.empty() && factory_commands_.empty()) throw std::invalid_argument("no command " + only);
    for (CLI::App* cmd : get_subcommands({})) bound_integer_options(*cmd);
    parse_complete_callback([this] {
      if (quiet_ && verbose_) throw CLI::ValidationError("--quiet and --verbose exclude each other");
      if (quiet_) {
        spdlog::set_level(spdlog::level::warn);
        ProgressBar::set_enabled(false);
      }
      if (verbose_) spdlog::set_level(spdlog::level::debug);
      for (const CLI::App* cmd : get_subcommands()) run_checks(cmd);
      if (check_only_) throw CLI::Success();
    });
  }

  // Parse and check, but do not run the command: parse() then ends with CLI::Success once every
  // option is converted and checked (for tests of the option layer).
  void set_check_only(bool check_only) { check_only_ = check_only; }

 private:
  bool quiet_ = false, verbose_ = false, check_only_ = false;
  std::vector<std::string> factory_commands_;  // the name of the command each factory run added

  // The command each of command_factories() adds, in order (learnt once, from a whole command line).
  static const std::vector<std::string>& command_names() {
    static const std::vector<std::string> names = CommandLine().factory_commands_;
    return names;
  }

  void apply_config(const std::string& file) {
    const auto commands = get_subcommands();
    if (commands.empty()) throw CLI::ConfigError("--config " + file + ": give a command to read the options of");
    apply_config_file(*commands.front(), file);
  }

  // An integer option without a declared range still refuses negative (if unsigned), overflowing,
  // fractional and exponent values, from the command line and from --config.
  static void bound_integer_options(CLI::App& cmd) {
    for (CLI::Option* o : cmd.get_options()) {
      const std::string full = o->get_type_name();  // "UINT", "INT:in [1, 4096]", ...
      const std::string type = full.substr(0, full.find(':'));
      if (type != "INT" && type != "UINT") continue;
      try {
        o->get_validator("INTEGER_RANGE");
        continue;
      } catch (const CLI::OptionNotFound&) {
      }
      o->check(integer_range(type == "UINT" ? 0 : std::numeric_limits<std::int64_t>::min(),
                             std::numeric_limits<std::int64_t>::max()));
    }
  }
};

}  // namespace slamvdb::cli
