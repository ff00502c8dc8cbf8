// Points as text (`query --at`, `--at-csv`): the whole input as a points file, and its first line as
// one --at value. Every point returned must be finite (the parser's promise).
#include <cmath>
#include <cstdlib>
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/point_text.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    for (const slamvdb::Vec3d& p : slamvdb::parse_points_text(text, "fuzz.csv").points)
      if (!p.allFinite()) std::abort();
  } catch (const slamvdb::Error&) {
  }
  try {
    if (!slamvdb::parse_point(text.substr(0, text.find('\n')), "--at").allFinite()) std::abort();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
