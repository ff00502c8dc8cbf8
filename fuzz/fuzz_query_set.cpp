// Query-set files (JSON: names, vectors, colours, void classes, model id).
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/query/query_set.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::QuerySet q = slamvdb::load_query_set(slamvdb::fuzz::write_input(data, size, "queries.json"));
    if (!q.vectors.allFinite() || q.vectors.rows() != q.size()) __builtin_trap();  // loading validates
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
