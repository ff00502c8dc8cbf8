// ROS 2 bags: the input is either a .db3 file read alone (first byte 0) or, after a first byte 1
// and a 4-byte little-endian length, a metadata.yaml of that length followed by the bag's only
// file, bag_0.db3. The reader opens the bag and reads every message, or throws slamvdb::Error.
#include <filesystem>
#include <fstream>

#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/rosbag2.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  try {
    std::filesystem::path path;
    if (data[0] == 0 || size < 5) {
      path = slamvdb::fuzz::write_input(data + 1, size - 1, "input.db3");
    } else {
      const std::size_t yaml = std::min<std::size_t>(size - 5, data[1] | data[2] << 8 | data[3] << 16 |
                                                                   static_cast<std::size_t>(data[4]) << 24);
      const std::filesystem::path db3 = slamvdb::fuzz::write_input(data + 5 + yaml, size - 5 - yaml, "bag_0.db3");
      path = db3.parent_path() / "bag";
      std::filesystem::create_directories(path);
      std::filesystem::rename(db3, path / "bag_0.db3");
      std::ofstream(path / "metadata.yaml", std::ios::binary).write(reinterpret_cast<const char*>(data + 5), yaml);
    }
    const auto reader = slamvdb::recording::open_rosbag2(path);
    slamvdb::recording::Message m;
    std::uint64_t n = 0;
    while (reader->next(m)) {
      if (m.channel == nullptr || m.index != n++) __builtin_trap();
      std::uint8_t sum = 0;
      for (const std::uint8_t b : m.data) sum = static_cast<std::uint8_t>(sum + b);
      asm volatile("" : : "r"(sum) : "memory");  // the bytes are read (ASan checks them)
    }
    reader->notes();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
