#pragma once
// The project's own shared libraries that are loaded only when a command needs them (dlopen), so
// that every other run does not pay for what they link. The TorchScript backend is one: linking
// libtorch into the CLI cost 0.7-1.0 s of CPU at every start (its static initialisers register
// thousands of operators), in every command, also `--help`, whether or not a network ran.
//
// Where a plugin is looked for, in this order (the first file that exists is loaded):
//   1. the directory of the running executable: the build tree puts plugins beside the CLI;
//   2. that directory + SLAMVDB_PLUGIN_RELDIR: an installed CLI (bin/ -> lib/slamvdb/);
//   3. the build tree's directory, compiled in: the Python module and programs run from elsewhere.
// Hand-written (a dozen lines over dlopen/dlsym): no Debian library does only this.
#include <string>

namespace slamvdb {

// The address of `symbol` in the plugin library `file` (e.g. "libslamvdb_torch_inference.so"),
// loaded on first use and kept loaded for the life of the process. Throws Error naming `what`
// (what the plugin is for), every place looked in, and the loader's reason.
void* plugin_symbol(const std::string& file, const char* symbol, const std::string& what);

// Throws Error if a plugin's table is of another version than this build's (a library from
// another build: "rebuild or reinstall both").
void check_plugin_version(const std::string& file, const std::string& what, int found, int expected);

// The table of functions a plugin exports through `symbol`, an extern "C" function returning
// `const Table*` whose first member is `int version`; checked against `expected_version`.
template <class Table>
const Table& plugin_exports(const std::string& file, const char* symbol, const std::string& what,
                            int expected_version) {
  using Entry = const Table* (*)();
  const Table* table = reinterpret_cast<Entry>(plugin_symbol(file, symbol, what))();
  check_plugin_version(file, what, table->version, expected_version);
  return *table;
}

}  // namespace slamvdb
