// ROS 1 bags (format 2.0): the bag header, the index (connections, chunk infos), chunks (none, bz2,
// lz4) read in time order within a small memory budget, and the linear reading of a bag without
// index or cut short; every message is read to the end.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/ros1_bag.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    slamvdb::recording::Ros1BagOptions options;
    options.chunk_memory_bytes = 1 << 16;  // small: the eviction and reloading paths run too
    const auto reader = slamvdb::recording::open_ros1_bag(slamvdb::fuzz::write_input(data, size, "input.bag"), options);
    (void)reader->describe();
    (void)reader->time_range();
    slamvdb::recording::Message m;
    std::uint64_t n = 0;
    unsigned sum = 0;
    while (n < 100000 && reader->next(m)) {
      if (!m.channel || m.index != n) __builtin_trap();
      if (!m.data.empty()) sum += m.data.front() + m.data.back();  // the view must be readable
      ++n;
    }
    if (reader->bytes_read() > 64 * reader->size_bytes() + (1 << 20)) __builtin_trap();  // no runaway re-reading
    (void)reader->notes();
    (void)sum;
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
