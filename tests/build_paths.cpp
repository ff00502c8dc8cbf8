// The one translation unit that holds the build's paths (see slamvdb/testing/build_paths.hpp).
#include "slamvdb/testing/build_paths.hpp"

namespace slamvdb::testing {
const char* build_cli_path() { return SLAMVDB_BUILD_CLI_PATH; }
const char* build_python() { return SLAMVDB_BUILD_PYTHON; }
const char* build_source_dir() { return SLAMVDB_BUILD_SOURCE_DIR; }
}  // namespace slamvdb::testing
