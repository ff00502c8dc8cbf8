// slamvdb: open-vocabulary semantic voxel mapping. One binary, one subcommand per job.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <new>

#include "command_registry.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"

int main(int argc, char** argv) {
  CLI::App app{"slamvdb: open-vocabulary semantic voxel maps from LiDAR and camera"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Show help for every subcommand");
  for (const auto& add : slamvdb::cli::command_factories()) add(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help exits 0; every usage error (a bad, missing or unknown option or value) exits 2.
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
