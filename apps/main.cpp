// slamvdb: open-vocabulary semantic voxel mapping. One binary, one subcommand per job.
// Exit codes: 0 success, 1 runtime error (bad input file, full disk, ...), 2 usage error.
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <new>
#include <string>

#include "command_line.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb_version.hpp"

namespace {

// The command's name: the first argument that is neither an option nor the value of a root option
// that takes one (--config FILE), or empty.
std::string command_name(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--config") {
      ++i;
      continue;
    }
    if (arg[0] != '-' && !arg.empty()) return arg;
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  // Interactive use: one line per message, no time stamps; logs (stderr not a terminal) keep them.
  if (isatty(fileno(stderr))) spdlog::set_pattern("%^%l%$: %v");

  slamvdb::cli::CommandLine app;
  app.set_version_flag("--version", std::string("slamvdb ") + SLAMVDB_VERSION + " (" + SLAMVDB_GIT_COMMIT + ")");
  const std::string command = command_name(argc, argv);
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
    // A problem with the --config file (yaml_config.hpp): its message names the file.
    std::fprintf(stderr, "%s\n", slamvdb::escape_control(e.what()).c_str());
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
  // Standard output is an output too (`query --at` prints its CSV there): a full disk or failing
  // device behind it is an error, not a silent exit 0 (core/output_file.hpp has the same rule).
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
    // On standard error: spdlog's default logger writes to standard output, which just failed.
    std::fprintf(stderr, "error: cannot write standard output: %s\n", std::strerror(errno));
    return 1;
  }
  return 0;
}
