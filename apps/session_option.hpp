#pragma once
// `--session NAME[,NAME]` on the commands that read a map file (export, query, classify): only the
// named sessions' submaps (sessions/session_selection.hpp), as `info` lists the sessions.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cstdio>
#include <string>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/sessions/session_selection.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli {

inline CLI::Option* add_session_option(CLI::App* cmd, std::vector<std::string>& sessions, const std::string& help) {
  return cmd->add_option("--session", sessions, help)->delimiter(',')->type_name("NAME[,NAME]");
}

// Loads `path`, only the named sessions' submaps when `sessions` is not empty. An unknown name is
// refused (exit 1, naming the sessions the file has) from the file's summary, before any voxel is
// read. Says on stderr what was kept (stdout may carry the command's data).
inline SemanticMap load_map_of_sessions(const std::string& path, const std::vector<std::string>& sessions) {
  if (sessions.empty()) return load_map(path);
  try {
    sessions::session_ids_named(read_map_summary(path).info, sessions);
  } catch (const Error& e) {
    throw Error(fmt::format("--session: {}: {}", path, e.what()));
  }
  SemanticMap map = load_map(path);
  const sessions::SessionSelection kept = sessions::keep_sessions(map, sessions);
  fmt::print(stderr, "--session {}: {} of {} submaps of {}\n", fmt::join(sessions, ","), kept.submaps_kept,
             kept.submaps_kept + kept.submaps_removed, path);
  return map;
}

}  // namespace slamvdb::cli
