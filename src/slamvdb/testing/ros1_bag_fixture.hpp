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
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"  // ReadMessage, read_all
#include "slamvdb/testing/run_command.hpp"

namespace slamvdb::testing {

// A simulated sequence (slamvdb synth), made once per process and shared by the bag tests.
inline const std::filesystem::path& ros1_bag_test_sequence() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() / ("slamvdb-ros1-sequence-" + std::to_string(::getpid()));
    std::filesystem::remove_all(d);
    const CommandResult r = run_cli("synth " + quote_path(d) + " --length 2 --lidar-columns 128 --image-size 64x40 --keep-no-return");
    if (r.exit_code != 0) ADD_FAILURE() << "synth failed: " << r.output;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(
          std::filesystem::temp_directory_path() / ("slamvdb-ros1-sequence-" + std::to_string(::getpid())), ec);
    });
    return d;
  }();
  return dir;
}

struct ManifestMessage {
  std::size_t seq = 0;
  std::string topic, type;
  std::int64_t log_time_ns = 0, stamp_ns = 0;
  std::size_t size = 0;
  std::uint32_t crc32 = 0;
};

struct WrittenBag {
  std::filesystem::path path;
  std::vector<ManifestMessage> messages;  // in the order written
  std::size_t in_finished_chunks = 0;     // --kill-after: the leading messages in finished chunks
  // The messages as a reader in log-time order gives them (equal times in the order written).
  std::vector<ManifestMessage> in_time_order() const {
    std::vector<ManifestMessage> sorted = messages;
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const auto& a, const auto& b) { return a.log_time_ns < b.log_time_ns; });
    return sorted;
  }
};

// Writes `dir/name` from the shared sequence with write_ros1_bag.py `options`.
inline WrittenBag write_ros1_bag(const std::filesystem::path& dir, const std::string& name, const std::string& options) {
  WrittenBag bag;
  bag.path = dir / name;
  const std::filesystem::path manifest = dir / (name + ".json");
  const std::filesystem::path script =
      std::filesystem::path(SLAMVDB_SOURCE_DIR) / "tests" / "recording_fixtures" / "write_ros1_bag.py";
  const CommandResult r = run_command("exec /usr/bin/python3 " + quote_path(script) + " " +
                                      quote_path(ros1_bag_test_sequence()) + " " + quote_path(bag.path) + " " +
                                      options + " --manifest " + quote_path(manifest));
  EXPECT_EQ(r.exit_code, 0) << "write_ros1_bag.py " << options << ":\n" << r.output;
  std::ifstream in(manifest);  // JSON lines, one per message in the order written
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    const nlohmann::json m = nlohmann::json::parse(line);
    bag.messages.push_back({m["seq"], m["topic"], m["type"], m["log_time_ns"], m["stamp_ns"], m["size"], m["crc32"]});
    if (m["in_finished_chunk"].get<bool>()) bag.in_finished_chunks = bag.messages.size();
  }
  return bag;
}

// Checks that `read` is `expected` (topic, type, log time, bytes), message by message.
inline void expect_same_messages(const std::vector<ReadMessage>& read, const std::vector<ManifestMessage>& expected) {
  ASSERT_EQ(read.size(), expected.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    SCOPED_TRACE("message " + std::to_string(i) + " (written " + std::to_string(expected[i].seq) + ")");
    EXPECT_EQ(read[i].index, i);
    EXPECT_EQ(read[i].topic, expected[i].topic);
    EXPECT_EQ(read[i].type, expected[i].type);
    EXPECT_EQ(read[i].log_time_ns, expected[i].log_time_ns);
    EXPECT_EQ(read[i].size, expected[i].size);
    EXPECT_EQ(read[i].crc32, expected[i].crc32);
  }
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
