#pragma once
// Where the tests find the CLI, Python and the source tree. The paths live in one translation unit
// (tests/build_paths.cpp), not on every test file's command line, so that a test file compiles the
// same in every checkout (compiler caches can share its object between worktrees). Every test file
// sees these through the test target's `-include` of this header; SLAMVDB_CLI_PATH,
// SLAMVDB_PYTHON and SLAMVDB_SOURCE_DIR expand to calls of the functions below.
namespace slamvdb::testing {
const char* build_cli_path();    // the slamvdb executable built with the tests
const char* build_python();      // the Python interpreter CMake found (Debian's, with torch and numpy)
const char* build_source_dir();  // the project's source tree
}  // namespace slamvdb::testing
