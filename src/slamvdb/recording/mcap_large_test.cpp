// A file over 4 GiB (sparse: a 4.5 GiB private record before the chunk, so it costs no disk):
// 64-bit offsets through the chunk index, the summary and linear reading, and nothing read whole.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/testing/mcap_assembly.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::recording {
namespace {

namespace fs = std::filesystem;
namespace ma = testing::mcap_assembly;

TEST(McapLargeFile, OffsetsPast4GiBAreReadThroughTheIndexAndLinearly) {
  const testing::TempDir tmp;
  constexpr std::uint64_t kPadding = (std::uint64_t{9} << 29);  // 4.5 GiB
  const std::string records = ma::schema(1, "std_msgs/msg/String", "ros2msg", "string data") +
                              ma::channel(7, 1, "/chatter", "cdr") + ma::message(7, 30, std::string("\0\1\0\0c", 5)) +
                              ma::message(7, 10, std::string("\0\1\0\0a", 5)) + ma::message(7, 20, std::string("\0\1\0\0b", 5));
  for (const bool summary : {true, false}) {
    SCOPED_TRACE(summary ? "with summary" : "without summary");
    const fs::path file = tmp.path / "large.mcap";
    const std::string head = ma::magic() + ma::header("ros2") + std::string(1, '\x80') + ma::le<std::uint64_t>(kPadding);
    const std::uint64_t chunk_offset = head.size() + kPadding;
    const std::string the_chunk = ma::chunk(10, 30, records);
    std::string tail = the_chunk + ma::data_end();
    const std::uint64_t summary_start = chunk_offset + tail.size();
    const std::string summary_records =
        summary ? ma::schema(1, "std_msgs/msg/String", "ros2msg", "string data") + ma::channel(7, 1, "/chatter", "cdr") +
                      ma::chunk_index(10, 30, chunk_offset, the_chunk.size(), {7}, "", records.size(), records.size()) +
                      ma::statistics(3, 10, 30, {{7, 3}})
                : "";
    tail += summary_records + ma::footer(summary ? summary_start : 0, summary_records);
    {
      std::ofstream(file, std::ios::binary) << head;
      std::error_code ec;
      fs::resize_file(file, chunk_offset, ec);  // a hole: no disk used
      if (ec) GTEST_SKIP() << "cannot make a sparse 4.5 GiB file here: " << ec.message();
      std::ofstream(file, std::ios::binary | std::ios::app) << tail;
    }
    ASSERT_GT(fs::file_size(file), std::uint64_t{1} << 32);
    const auto reader = open_mcap(file);
    ASSERT_EQ(reader->channels().size(), 1u);
    EXPECT_EQ(reader->channels()[0].topic, "/chatter");
    EXPECT_EQ(reader->channels()[0].type, "std_msgs/String");
    EXPECT_EQ(reader->channels()[0].message_count, 3u);
    std::string order;
    Message m;
    while (reader->next(m)) order += static_cast<char>(m.data.back());
    EXPECT_EQ(order, "abc");  // log-time order, not file order
    EXPECT_LT(reader->bytes_read(), 10000u);  // the padding was never read
    fs::remove(file);
  }
}

}  // namespace
}  // namespace slamvdb::recording
