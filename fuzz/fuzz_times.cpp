// times.txt (one stamp per line, strictly increasing).
#include <cmath>

#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/sequence_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto stamps = slamvdb::read_stamps(slamvdb::fuzz::write_input(data, size, "times.txt"));
    for (std::size_t i = 0; i < stamps.size(); ++i)
      if (!std::isfinite(stamps[i]) || (i > 0 && !(stamps[i] > stamps[i - 1]))) __builtin_trap();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
