// The ROS 1 bag reader on bags written by ROS's own writer (Debian's python3-rosbag): every
// compression, time order across chunks, selection, bags without index or cut short, damage.
#include "slamvdb/recording/ros1_bag.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/ros1_bag_fixture.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::recording {
namespace ros1_bag_test {

namespace fs = std::filesystem;
using testing::error_of;
using testing::read_all;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }
std::string joined(const std::vector<std::string>& lines) {
  std::string all;
  for (const auto& l : lines) all += l + "\n";
  return all;
}

TEST(Ros1Bag, ReadsEveryMessageOfEachCompressionInTimeOrder) {
  testing::TempDir tmp;
  for (const std::string compression : {"none", "bz2", "lz4"}) {
    SCOPED_TRACE(compression);
    // Chunks of 64 kB: a scan is larger, so every scan starts a chunk.
    const auto bag = testing::write_ros1_bag(tmp.path, compression + ".bag",
                                             "--compression " + compression + " --chunk-size 65536");
    ASSERT_GT(bag.messages.size(), 10u);
    const auto reader = open_ros1_bag(bag.path);
    EXPECT_EQ(reader->describe(), "ROS 1 bag (format 2.0, " + (compression == "none" ? "uncompressed" : compression) +
                                      " chunks, indexed)");
    EXPECT_TRUE(reader->notes().empty()) << joined(reader->notes());
    EXPECT_EQ(reader->size_bytes(), fs::file_size(bag.path));
    ASSERT_EQ(reader->channels().size(), 6u);
    for (const Channel& channel : reader->channels()) {
      const auto count = std::count_if(bag.messages.begin(), bag.messages.end(),
                                       [&](const auto& m) { return m.topic == channel.topic; });
      EXPECT_EQ(channel.message_count, static_cast<std::uint64_t>(count)) << channel.topic;
      EXPECT_EQ(channel.serialization, Serialization::kRos1);
      EXPECT_FALSE(channel.definition.empty()) << channel.topic;
    }
    const auto expected = bag.in_time_order();
    ASSERT_TRUE(reader->time_range());
    EXPECT_EQ(reader->time_range()->start_ns, expected.front().log_time_ns);
    EXPECT_EQ(reader->time_range()->end_ns, expected.back().log_time_ns);
    EXPECT_TRUE(testing::same_messages(expected, read_all(*reader)));
    EXPECT_GT(reader->bytes_read(), fs::file_size(bag.path) / 2);
    EXPECT_LE(reader->bytes_read(), fs::file_size(bag.path));
  }
}

TEST(Ros1Bag, TimeOrderAcrossChunksThatOverlap) {
  testing::TempDir tmp;
  // Topic by topic in small chunks: every chunk overlaps the others in time, and the messages of
  // all topics must be merged across them.
  const auto bag = testing::write_ros1_bag(tmp.path, "overlap.bag",
                                           "--compression lz4 --chunk-size 4096 --write-order topic");
  const auto expected = bag.in_time_order();
  ASSERT_FALSE(std::is_sorted(bag.messages.begin(), bag.messages.end(),
                              [](const auto& a, const auto& b) { return a.log_time_ns < b.log_time_ns; }))
      << "the writer did not write out of time order";
  const auto reader = open_ros1_bag(bag.path);
  EXPECT_TRUE(testing::same_messages(expected, read_all(*reader)));
  EXPECT_TRUE(reader->notes().empty()) << joined(reader->notes());
  // With room for no chunk at all: chunks are dropped and decompressed again, the order is the same.
  Ros1BagOptions tight;
  tight.chunk_memory_bytes = 1;
  const auto again = open_ros1_bag(bag.path, tight);
  EXPECT_TRUE(testing::same_messages(expected, read_all(*again)));
  EXPECT_GT(again->bytes_read(), reader->bytes_read()) << "chunks were read again";
}

TEST(Ros1Bag, SelectedChannelsOnlyAndChunksWithoutThemUnread) {
  testing::TempDir tmp;
  const auto bag = testing::write_ros1_bag(tmp.path, "select.bag",
                                           "--compression lz4 --chunk-size 4096 --write-order topic");
  const auto reader = open_ros1_bag(bag.path);
  // Camera info: small messages whose chunks hold no scan.
  const std::string topic = "/pylon_camera_node/camera_info";
  std::uint32_t camera_info = 0;
  for (const Channel& c : reader->channels())
    if (c.topic == topic) camera_info = c.id;
  reader->select({camera_info});
  std::vector<testing::WrittenMessage> expected;
  for (const auto& m : bag.in_time_order())
    if (m.topic == topic) expected.push_back(m);
  EXPECT_TRUE(testing::same_messages(expected, read_all(*reader)));
  EXPECT_LT(reader->bytes_read(), fs::file_size(bag.path) / 10) << "the chunks of other topics were skipped";
}

TEST(Ros1Bag, UnindexedBagIsReadLinearlyWithANote) {
  testing::TempDir tmp;
  for (const std::string compression : {"none", "bz2", "lz4"}) {
    SCOPED_TRACE(compression);
    const auto bag = testing::write_ros1_bag(tmp.path, compression + ".bag",
                                             "--no-index --chunk-size 65536 --compression " + compression);
    const auto reader = open_ros1_bag(bag.path);
    EXPECT_TRUE(contains(reader->describe(), "no index: read linearly")) << reader->describe();
    EXPECT_FALSE(reader->time_range());
    EXPECT_TRUE(testing::same_messages(bag.in_time_order(), read_all(*reader)));
    ASSERT_EQ(reader->notes().size(), 1u) << joined(reader->notes());
    EXPECT_TRUE(contains(reader->notes()[0], "no index (the bag header's index_pos is 0")) << reader->notes()[0];
    ASSERT_EQ(reader->channels().size(), 6u);
    EXPECT_FALSE(reader->channels()[0].message_count);
  }
}

TEST(Ros1Bag, RecorderKilledWhileWritingAChunk) {
  testing::TempDir tmp;
  for (const std::string compression : {"none", "bz2", "lz4"}) {
    SCOPED_TRACE(compression);
    const auto bag = testing::write_ros1_bag(tmp.path, compression + ".bag",
                                             "--kill-after 12 --chunk-size 150000 --compression " + compression);
    ASSERT_EQ(bag.messages.size(), 12u);
    ASSERT_GT(bag.in_finished_chunks, 0u);
    ASSERT_LT(bag.in_finished_chunks, 12u) << "the last chunk must be unfinished";
    const auto reader = open_ros1_bag(bag.path);
    const auto read = read_all(*reader);
    // What is read is what was written, in order, at least up to the last finished chunk; an
    // uncompressed unfinished chunk is read whole (its records are all on disk).
    ASSERT_GE(read.size(), bag.in_finished_chunks) << joined(reader->notes());
    if (compression == "none") {
      EXPECT_EQ(read.size(), 12u);
    }
    const std::vector<testing::WrittenMessage> prefix(bag.messages.begin(), bag.messages.begin() + read.size());
    EXPECT_TRUE(testing::same_messages(prefix, read));
    EXPECT_TRUE(contains(joined(reader->notes()), "unfinished")) << joined(reader->notes());
  }
}

TEST(Ros1Bag, CutMidChunkRecoversWhatPrecedesTheCut) {
  testing::TempDir tmp;
  for (const std::string compression : {"none", "lz4", "bz2"}) {
    SCOPED_TRACE(compression);
    const auto bag = testing::write_ros1_bag(tmp.path, compression + ".bag",
                                             "--chunk-size 65536 --compression " + compression);
    auto bytes = testing::file_bytes(bag.path);
    std::vector<testing::BagRecordSpan> chunks;
    for (const auto& r : testing::bag_records(bytes))
      if (r.op == 0x05) chunks.push_back(r);
    ASSERT_GE(chunks.size(), 3u);
    bytes.resize(chunks[2].data_offset + chunks[2].data_length / 2);
    const fs::path cut = tmp.path / ("cut-" + compression + ".bag");
    testing::write_bytes(cut, bytes);
    const auto reader = open_ros1_bag(cut);
    const auto read = read_all(*reader);
    const std::string notes = joined(reader->notes());
    EXPECT_TRUE(contains(notes, "outside the file")) << notes;
    EXPECT_TRUE(contains(notes, "is cut short by the end of the file")) << notes;
    ASSERT_GE(read.size(), 3u);
    const std::vector<testing::WrittenMessage> prefix(bag.messages.begin(), bag.messages.begin() + read.size());
    EXPECT_TRUE(testing::same_messages(prefix, read));
  }
}

// A copy of `bag` with a hole of `shift` bytes before its first chunk (a sparse file): every
// chunk, index record and offset beyond 4 GB.
fs::path shifted_copy(const fs::path& bag, std::uint64_t shift, const fs::path& out) {
  const auto bytes = testing::file_bytes(bag);
  const auto records = testing::bag_records(bytes);
  std::vector<std::uint8_t> head(bytes.begin(), bytes.begin() + records.at(1).offset);
  std::vector<std::uint8_t> tail(bytes.begin() + records.at(1).offset, bytes.end());
  const auto add = [&](std::vector<std::uint8_t>& b, std::size_t at) {
    std::uint64_t v;
    std::memcpy(&v, b.data() + at, 8);
    v += shift;
    std::memcpy(b.data() + at, &v, 8);
  };
  add(head, records[0].field_value_offsets.at("index_pos"));
  for (const auto& r : records)
    if (r.op == 0x06) add(tail, r.field_value_offsets.at("chunk_pos") - records[1].offset);
  std::ofstream f(out, std::ios::binary);
  f.write(reinterpret_cast<const char*>(head.data()), head.size());
  f.seekp(static_cast<std::streamoff>(records[1].offset + shift));
  f.write(reinterpret_cast<const char*>(tail.data()), tail.size());
  return out;
}

TEST(Ros1Bag, FilesOver4GB) {
  testing::TempDir tmp;
  const auto bag = testing::write_ros1_bag(tmp.path, "small.bag", "--compression lz4 --chunk-size 65536");
  const fs::path big = shifted_copy(bag.path, std::uint64_t{5} << 30, tmp.path / "big.bag");
  ASSERT_GT(fs::file_size(big), std::uint64_t{5} << 30);
  const auto reader = open_ros1_bag(big);
  EXPECT_TRUE(reader->notes().empty()) << joined(reader->notes());
  EXPECT_TRUE(testing::same_messages(bag.in_time_order(), read_all(*reader)));
  EXPECT_LT(reader->bytes_read(), fs::file_size(bag.path)) << "the hole is never read";
}

TEST(Ros1Bag, DamagedChunksAreErrorsNamingTheOffset) {
  testing::TempDir tmp;
  for (const std::string compression : {"lz4", "bz2"}) {
    const auto bag = testing::write_ros1_bag(tmp.path, compression + ".bag", "--compression " + compression);
    const auto bytes = testing::file_bytes(bag.path);
    const auto records = testing::bag_records(bytes);
    const auto chunk = *std::find_if(records.begin(), records.end(), [](const auto& r) { return r.op == 0x05; });
    const auto read_damaged = [&](const std::vector<std::uint8_t>& damaged) {
      const fs::path path = tmp.path / "damaged.bag";
      testing::write_bytes(path, damaged);
      return error_of([&] { read_all(*open_ros1_bag(path)); });
    };
    // Corrupt compressed data: a checksum or the decoder catches it.
    auto damaged = bytes;
    for (std::size_t i = 0; i < 64; ++i) damaged[chunk.data_offset + chunk.data_length / 2 + i] ^= 0x5a;
    std::string e = read_damaged(damaged);
    EXPECT_TRUE(contains(e, "at offset " + std::to_string(chunk.offset) + ": the chunk's " + compression +
                                " data are damaged"))
        << e;
    // An unknown compression name.
    damaged = bytes;
    damaged[chunk.field_value_offsets.at("compression")] = 'z';
    e = read_damaged(damaged);
    EXPECT_TRUE(contains(e, "unknown chunk compression \"z" + compression.substr(1) + "\"")) << e;
    // A record header with an absurd length.
    damaged = bytes;
    damaged[chunk.offset + 3] = 0x7f;
    e = read_damaged(damaged);
    EXPECT_TRUE(contains(e, "at offset " + std::to_string(chunk.offset))) << e;
    EXPECT_TRUE(contains(e, "a record header of 2130706")) << e;
    // The bag header's.
    damaged = bytes;
    damaged[16] = 0x7f;
    e = error_of([&] {
      testing::write_bytes(tmp.path / "header.bag", damaged);
      open_ros1_bag(tmp.path / "header.bag");
    });
    EXPECT_TRUE(contains(e, "at offset 13: the bag header record is damaged")) << e;
  }
}

TEST(Ros1Bag, DamageInAnUnindexedBagStopsReadingWithANote) {
  testing::TempDir tmp;
  const auto bag = testing::write_ros1_bag(tmp.path, "u.bag", "--no-index --chunk-size 65536 --compression lz4");
  auto bytes = testing::file_bytes(bag.path);
  std::vector<testing::BagRecordSpan> chunks;
  for (const auto& r : testing::bag_records(bytes))
    if (r.op == 0x05) chunks.push_back(r);
  ASSERT_GE(chunks.size(), 3u);
  bytes[chunks[2].offset + 3] = 0x7f;  // the third chunk's header length
  testing::write_bytes(bag.path, bytes);
  const auto reader = open_ros1_bag(bag.path);
  const auto read = read_all(*reader);
  EXPECT_TRUE(contains(joined(reader->notes()), "reading stopped at offset " + std::to_string(chunks[2].offset)))
      << joined(reader->notes());
  const std::vector<testing::WrittenMessage> prefix(bag.messages.begin(), bag.messages.begin() + read.size());
  EXPECT_TRUE(testing::same_messages(prefix, read));
  EXPECT_GE(read.size(), 3u);
}

TEST(Ros1Bag, WhatIsNotABagIsAnErrorNamingThePath) {
  testing::TempDir tmp;
  std::ofstream(tmp.path / "text.bag") << "hello, this is not a bag at all\n";
  std::ofstream(tmp.path / "old.bag") << "#ROSRECORD V1.2\nmore bytes";
  std::ofstream(tmp.path / "empty.bag");
  EXPECT_TRUE(contains(error_of([&] { open_ros1_bag(tmp.path / "text.bag"); }), "text.bag\" does not start with"));
  EXPECT_TRUE(contains(error_of([&] { open_ros1_bag(tmp.path / "old.bag"); }), "format 1.x"));
  EXPECT_TRUE(contains(error_of([&] { open_ros1_bag(tmp.path / "empty.bag"); }), "too short for a bag"));
  EXPECT_TRUE(contains(error_of([&] { open_ros1_bag(tmp.path); }), "is a directory"));
  EXPECT_TRUE(contains(error_of([&] { open_ros1_bag(tmp.path / "missing.bag"); }), "does not exist"));
}

}  // namespace ros1_bag_test
}  // namespace slamvdb::recording
