#pragma once
// Each subcommand lives in its own apps/cmd_*.cpp and registers itself here at start-up, so
// adding a command never touches main.cpp.
#include <CLI/CLI.hpp>
#include <functional>
#include <vector>

namespace slamvdb::cli {

using CommandFactory = std::function<void(CLI::App& root)>;

inline std::vector<CommandFactory>& command_factories() {
  static std::vector<CommandFactory> factories;
  return factories;
}

struct RegisterCommand {
  explicit RegisterCommand(CommandFactory f) { command_factories().push_back(std::move(f)); }
};

}  // namespace slamvdb::cli
