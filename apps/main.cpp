// slamvdb: open-vocabulary semantic voxel mapping. One binary, one subcommand per job.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>

#include "command_registry.hpp"
#include "slamvdb/core/error.hpp"

int main(int argc, char** argv) {
  CLI::App app{"slamvdb: open-vocabulary semantic voxel maps from LiDAR and camera"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Show help for every subcommand");
  for (const auto& add : slamvdb::cli::command_factories()) add(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const slamvdb::Error& e) {
    spdlog::error("{}", e.what());
    return 1;
  } catch (const std::exception& e) {
    spdlog::error("unexpected failure: {}", e.what());
    return 2;
  }
  return 0;
}
