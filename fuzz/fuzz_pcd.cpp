// PCD files (ascii, binary, binary_compressed; any field set with x y z).
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/pcd.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::PcdCloud c = slamvdb::read_pcd(slamvdb::fuzz::write_input(data, size, "scan.pcd"));
    if (!c.intensity.empty() && c.intensity.size() != c.points.size()) __builtin_trap();
    if (!c.time.empty() && c.time.size() != c.points.size()) __builtin_trap();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
