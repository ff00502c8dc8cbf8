#pragma once
// For tests only: ROS 1 bags written by ROS's own writer (Debian's python3-rosbag, through
// tests/recording_fixtures/write_ros1_bag.py) from a small simulated sequence, with the manifest
// the writer dumps (topic, type, log time, size and CRC-32 of every message, in the order
// written, JSON lines), and a walker of the bag's top-level records for tests that damage a bag on purpose.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {

// A SIMULATED sequence (2 m, 128 LiDAR columns, 64 x 40 images, no-return points kept as zeros),
// made once per process and shared by the bag tests.
inline const std::filesystem::path& ros1_bag_test_sequence() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() / ("slamvdb-ros1-sequence-" + std::to_string(::getpid()));
    synth::SynthConfig config;
    config.length_m = 2;
    config.lidar.columns = 128;
    config.image_width = 64;
    config.image_height = 40;
    config.keep_no_return = true;
    write_recording_sequence(d, config);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(
          std::filesystem::temp_directory_path() / ("slamvdb-ros1-sequence-" + std::to_string(::getpid())), ec);
    });
    return d;
  }();
  return dir;
}

struct WrittenBag {
  std::filesystem::path path;
  std::vector<WrittenMessage> messages;  // in the order written
  std::size_t in_finished_chunks = 0;    // --kill-after: the leading messages in finished chunks
  // The messages as a reader in log-time order gives them (equal times in the order written).
  std::vector<WrittenMessage> in_time_order() const { return in_log_time_order(messages); }
};

// Writes `dir/name` from the shared sequence with write_ros1_bag.py `options`, and reads its manifest.
inline WrittenBag write_ros1_bag(const std::filesystem::path& dir, const std::string& name, const std::string& options) {
  WrittenBag bag;
  bag.path = dir / name;
  const std::filesystem::path manifest = dir / (name + ".json");
  run_fixture_writer("write_ros1_bag.py", quote_path(ros1_bag_test_sequence()) + " " + quote_path(bag.path) + " " +
                                              options + " --manifest " + quote_path(manifest));
  bag.messages = read_manifest(manifest);
  for (std::size_t i = 0; i < bag.messages.size(); ++i)
    if (bag.messages[i].in_finished_chunk) bag.in_finished_chunks = i + 1;
  return bag;
}

inline std::vector<std::uint8_t> file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
inline void write_bytes(const std::filesystem::path& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

// The top-level records of a bag, walked here independently of the reader (format 2.0: uint32
// header length, header fields "name=value", uint32 data length, data).
struct BagRecordSpan {
  std::size_t offset = 0, header_offset = 0, header_length = 0, data_offset = 0, data_length = 0;
  std::uint8_t op = 0;
  std::map<std::string, std::size_t> field_value_offsets;  // name -> offset of its value in the file
};
inline std::uint32_t le32(const std::vector<std::uint8_t>& b, std::size_t at) {
  std::uint32_t v;
  std::memcpy(&v, b.data() + at, 4);
  return v;
}
inline std::vector<BagRecordSpan> bag_records(const std::vector<std::uint8_t>& bytes) {
  std::vector<BagRecordSpan> records;
  std::size_t at = 13;
  while (at + 8 <= bytes.size()) {
    BagRecordSpan r;
    r.offset = at;
    r.header_offset = at + 4;
    r.header_length = le32(bytes, at);
    r.data_offset = r.header_offset + r.header_length + 4;
    if (r.data_offset > bytes.size()) break;
    r.data_length = le32(bytes, r.data_offset - 4);
    for (std::size_t f = r.header_offset; f < r.header_offset + r.header_length;) {
      const std::uint32_t length = le32(bytes, f);
      const std::string field(bytes.begin() + f + 4, bytes.begin() + f + 4 + length);
      const std::string name = field.substr(0, field.find('='));
      r.field_value_offsets[name] = f + 4 + name.size() + 1;
      if (name == "op") r.op = bytes[f + 4 + name.size() + 1];
      f += 4 + length;
    }
    records.push_back(r);
    at = r.data_offset + r.data_length;
  }
  return records;
}

}  // namespace slamvdb::testing
