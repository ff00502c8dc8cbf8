// slamvdb: open-vocabulary semantic voxel mapping. One binary, one subcommand per job.
// Exit codes: 0 success, 1 runtime error (bad input file, full disk, ...), 2 usage error.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <exception>
#include <new>
#include <string>

#include "command_overview.hpp"
#include "command_registry.hpp"
#include "progress.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb_version.hpp"
#include "yaml_config.hpp"

namespace {

// The first argument that is not an option: the command's name, or empty.
std::string command_name(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (argv[i][0] != '-' && argv[i][0] != 0) return argv[i];
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  // Interactive use: one line per message, no time stamps; logs (stderr not a terminal) keep them.
  if (isatty(fileno(stderr))) spdlog::set_pattern("%^%l%$: %v");

  CLI::App app{"slamvdb: open-vocabulary semantic voxel maps from LiDAR and camera"};
  app.require_subcommand(1);
  app.formatter(std::make_shared<slamvdb::cli::CommandOverviewFormatter>());  // commands in workflow order
  app.fallthrough();  // --quiet / --verbose are accepted after the command too
  app.set_help_all_flag("--help-all", "Show help for every subcommand");
  app.set_version_flag("--version", std::string("slamvdb ") + SLAMVDB_VERSION + " (" + SLAMVDB_GIT_COMMIT + ")");
  bool quiet = false, verbose = false;
  app.add_flag("-q,--quiet", quiet, "Print only warnings and errors (no progress bars)");
  app.add_flag("-v,--verbose", verbose, "Print debug messages too");
  app.parse_complete_callback([&] {
    if (quiet && verbose) throw CLI::ValidationError("--quiet and --verbose exclude each other");
    if (quiet) {
      spdlog::set_level(spdlog::level::warn);
      slamvdb::cli::ProgressBar::set_enabled(false);
    }
    if (verbose) spdlog::set_level(spdlog::level::debug);
  });
  for (const auto& add : slamvdb::cli::command_factories()) add(app);
  const std::string command = command_name(argc, argv);
  slamvdb::cli::add_yaml_config(app, command);
  try {
    const auto subs = app.get_subcommands({});
    if (!command.empty() && std::none_of(subs.begin(), subs.end(), [&](const CLI::App* s) { return s->check_name(command); })) {
      std::string commands;
      for (const CLI::App* sub : app.get_subcommands({})) commands += (commands.empty() ? "" : ", ") + sub->get_name();
      std::fprintf(stderr, "slamvdb: unknown command '%s'; commands: %s (slamvdb --help)\n",
                   slamvdb::escape_control(command).c_str(), commands.c_str());
      return 2;
    }
    app.parse(argc, argv);
  } catch (const CLI::ConfigError& e) {
    // CLI11 names its own formats ("INI was not able to parse map.x"): say what was wrong in ours.
    std::string message = e.what();
    if (const auto at = message.find("INI was not able to parse "); at != std::string::npos)
      message = "--config: '" + message.substr(at + 26) + "' is not an option of this command";
    std::fprintf(stderr, "%s\n", slamvdb::escape_control(message).c_str());
    return 2;
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every usage error (a bad, missing or unknown option or value) exits 2.
    return app.exit(e) == 0 ? 0 : 2;
  } catch (const slamvdb::Error& e) {
    // Messages quote file names and file contents: printed with control characters escaped.
    spdlog::error("{}", slamvdb::escape_control(e.what()));
    return 1;
  } catch (const std::bad_alloc&) {
    spdlog::error("out of memory");
    return 1;
  } catch (const std::exception& e) {
    // Not a usage error either (e.g. a file system failure): a runtime error, exit code 1.
    spdlog::error("{}", slamvdb::escape_control(e.what()));
    return 1;
  }
  return 0;
}
