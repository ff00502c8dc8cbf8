// Map files (SQLite, format v1 and v2): loading validates checksums and meaning, so whatever loads
// holds only finite values and reads through the global index.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/map_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto path = slamvdb::fuzz::write_input(data, size, "map.svdb");
    (void)slamvdb::read_map_summary(path);
    const slamvdb::SemanticMap map = slamvdb::load_map(path);
    if (!slamvdb::testing::first_non_finite_value(map).empty()) __builtin_trap();
    std::size_t cells = 0;
    map.read_index([&](const slamvdb::GlobalIndex& index) { cells = index.size(); });
    if (cells != map.num_index_cells()) __builtin_trap();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
