// MCAP files (any chunk compression, with or without a summary): the reader opens them, lists the
// channels and reads every message, or throws slamvdb::Error.
#include <set>

#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/mcap.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto reader = slamvdb::recording::open_mcap(slamvdb::fuzz::write_input(data, size, "input.mcap"));
    const auto& channels = reader->channels();
    std::set<std::uint32_t> ids;
    for (const auto& c : channels) ids.insert(c.id);
    slamvdb::recording::Message m;
    std::uint64_t n = 0;
    while (reader->next(m)) {
      // Every message on a listed channel, numbered in order, its bytes inside what was read.
      if (m.channel < channels.data() || m.channel >= channels.data() + channels.size()) __builtin_trap();
      if (m.index != n++) __builtin_trap();
      std::uint8_t sum = 0;
      for (const std::uint8_t b : m.data) sum = static_cast<std::uint8_t>(sum + b);
      asm volatile("" : : "r"(sum) : "memory");  // the bytes are read (ASan checks them)
      if (n == 2 && !ids.empty()) reader->select({*ids.begin()});
    }
    reader->notes();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
