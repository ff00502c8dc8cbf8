#include "slamvdb/core/plugin_library.hpp"

#include <dlfcn.h>
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <vector>

#include "slamvdb/core/error.hpp"

#ifndef SLAMVDB_PLUGIN_RELDIR
#define SLAMVDB_PLUGIN_RELDIR "../lib/slamvdb"
#endif
#ifndef SLAMVDB_BUILD_PLUGIN_DIR
#define SLAMVDB_BUILD_PLUGIN_DIR ""
#endif

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> plugin_candidates(const std::string& file) {
  std::vector<fs::path> out;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    out.push_back(exe.parent_path() / file);
    out.push_back((exe.parent_path() / SLAMVDB_PLUGIN_RELDIR / file).lexically_normal());
  }
  const fs::path built = fs::path(SLAMVDB_BUILD_PLUGIN_DIR) / file;
  if (*SLAMVDB_BUILD_PLUGIN_DIR && std::find(out.begin(), out.end(), built) == out.end()) out.push_back(built);
  return out;
}

}  // namespace

void* plugin_symbol(const std::string& file, const char* symbol, const std::string& what) {
  // dlopen and dlsym are thread-safe; the lock only keeps two first users from both reporting.
  static std::mutex mutex;
  const std::lock_guard lock(mutex);
  std::string looked;
  for (const fs::path& candidate : plugin_candidates(file)) {
    looked += fmt::format("{}{}", looked.empty() ? "" : ", ", candidate.string());
    std::error_code ec;
    if (!fs::exists(candidate, ec)) continue;
    // RTLD_LOCAL: the plugin's own copies of the project's code stay its own; never unloaded.
    void* handle = ::dlopen(candidate.c_str(), RTLD_NOW | RTLD_LOCAL | RTLD_NODELETE);
    if (!handle) throw Error(fmt::format("{}: cannot load {}: {}", what, candidate.string(), ::dlerror()));
    void* address = ::dlsym(handle, symbol);
    if (!address) throw Error(fmt::format("{}: {} has no {}: {}", what, candidate.string(), symbol, ::dlerror()));
    return address;
  }
  throw Error(fmt::format("{}: {} was not found (looked in: {}); it is built beside the slamvdb executable and "
                          "installed in its lib/slamvdb folder",
                          what, file, looked));
}

void check_plugin_version(const std::string& file, const std::string& what, int found, int expected) {
  if (found != expected)
    throw Error(fmt::format("{}: {} is version {}, this slamvdb needs {}: it is from another build (rebuild or "
                            "reinstall both)",
                            what, file, found, expected));
}

}  // namespace slamvdb
