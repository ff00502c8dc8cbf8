// Damaged MCAP files (written by @mcap/core, then cut or altered here): each a clear Error naming
// the file and the place, or a recovery with a note, never a crash.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/recording_fixtures.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb::recording {
namespace {

namespace fs = std::filesystem;
using testing::error_of;

class McapDamage : public testing::RecordingFixtureTest {
 protected:
  static fs::path write(const std::string& name, const std::string& options) {
    return RecordingFixtureTest::write("write_mcap.mjs", name + ".mcap", options);
  }
  // A copy of `file` with `bytes` as its content.
  static fs::path altered(const std::string& name, const std::string& bytes) {
    const fs::path out = dir() / name;
    std::ofstream(out, std::ios::binary) << bytes;
    return out;
  }
};

std::uint64_t le64(const std::string& b, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(b[at + i])) << (8 * i);
  return v;
}
void set_le64(std::string& b, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + i] = static_cast<char>(v >> (8 * i));
}

struct RecordAt {
  int opcode;
  std::size_t offset;
  std::uint64_t length;
};
// Records from `pos` on (opcode u8, length u64, content), walked independently of the reader, up
// to the footer or `end`.
std::vector<RecordAt> records_from(const std::string& b, std::size_t pos, std::size_t end) {
  std::vector<RecordAt> out;
  while (pos + 9 <= end) {
    const RecordAt r{static_cast<unsigned char>(b[pos]), pos, le64(b, pos + 1)};
    out.push_back(r);
    if (r.opcode == 0x02) break;
    pos += 9 + r.length;
  }
  return out;
}
std::vector<RecordAt> records_of(const std::string& b, int opcode) {
  std::vector<RecordAt> out;
  for (const RecordAt& r : records_from(b, 8, b.size() - 8))
    if (r.opcode == opcode) out.push_back(r);
  return out;
}

TEST_F(McapDamage, FileCutInsideAChunkIsReadUpToThatChunkWithANote) {
  const fs::path file = write("cut", "--compression zstd --chunk-size 100000");
  const std::string bytes = testing::read_text_file(file);
  const auto chunks = records_of(bytes, 0x06);
  ASSERT_GE(chunks.size(), 4u);
  const RecordAt& cut_chunk = chunks[2];
  const fs::path cut = altered("cut_inside.mcap", bytes.substr(0, cut_chunk.offset + cut_chunk.length / 2));

  const auto reader = open_mcap(cut);
  const std::string notes = testing::notes_text(*reader);
  EXPECT_NE(notes.find("ends inside the Chunk record at offset " + std::to_string(cut_chunk.offset)), std::string::npos)
      << notes;
  EXPECT_NE(notes.find(cut.string()), std::string::npos) << notes;
  const auto read = testing::read_all(*reader);
  const auto expected = testing::in_log_time_order(testing::read_manifest(manifest_of(file)));
  ASSERT_GT(read.size(), 0u);
  ASSERT_LT(read.size(), expected.size());
  // What was read is what was written before the cut, in order.
  EXPECT_TRUE(testing::same_messages({expected.begin(), expected.begin() + static_cast<long>(read.size())}, read));
}

TEST_F(McapDamage, FileWithoutItsEndIsReadWhole) {
  // A recorder stopped before writing the Data End record, the summary and the footer.
  const fs::path file = write("unfinished", "--compression lz4 --chunk-size 100000");
  const std::string bytes = testing::read_text_file(file);
  const auto data_end = records_of(bytes, 0x0F);
  ASSERT_EQ(data_end.size(), 1u);
  const fs::path cut = altered("unfinished_cut.mcap", bytes.substr(0, data_end[0].offset));
  const auto reader = open_mcap(cut);
  EXPECT_NE(testing::notes_text(*reader).find("has no footer"), std::string::npos) << testing::notes_text(*reader);
  EXPECT_TRUE(testing::same_messages(testing::in_log_time_order(testing::read_manifest(manifest_of(file))),
                                     testing::read_all(*reader)));
}

TEST_F(McapDamage, ChunkWhoseCrcDoesNotMatchIsAnErrorNamingIt) {
  for (const bool summary : {true, false}) {
    SCOPED_TRACE(summary ? "with summary" : "without summary");
    const fs::path file = write("crc", std::string("--chunk-size 100000") + (summary ? "" : " --no-summary"));
    std::string bytes = testing::read_text_file(file);
    const auto chunks = records_of(bytes, 0x06);
    const auto biggest = *std::max_element(chunks.begin(), chunks.end(),
                                           [](const RecordAt& a, const RecordAt& b) { return a.length < b.length; });
    bytes[biggest.offset + biggest.length / 2] ^= 0x10;  // inside a point cloud's data
    const fs::path damaged = altered("crc_damaged.mcap", bytes);
    const std::string error = error_of([&] {
      const auto reader = open_mcap(damaged);  // without a summary, the first pass finds it
      testing::read_all(*reader);
    });
    EXPECT_NE(error.find("the Chunk at offset " + std::to_string(biggest.offset)), std::string::npos) << error;
    EXPECT_NE(error.find("CRC"), std::string::npos) << error;
    EXPECT_NE(error.find(damaged.string()), std::string::npos) << error;
  }
}

TEST_F(McapDamage, DamagedCompressedDataIsAnErrorNamingTheChunk) {
  for (const std::string compression : {"lz4", "zstd"}) {
    const fs::path file = write("compressed_" + compression, "--chunk-size 100000 --compression " + compression);
    std::string bytes = testing::read_text_file(file);
    const auto chunks = records_of(bytes, 0x06);
    const RecordAt& chunk = chunks[1];
    bytes[chunk.offset + chunk.length / 2] ^= 0x5a;
    const fs::path damaged = altered("damaged_" + compression + ".mcap", bytes);
    const std::string error = error_of([&] { testing::read_all(*open_mcap(damaged)); });
    EXPECT_NE(error.find("the Chunk at offset " + std::to_string(chunk.offset)), std::string::npos) << error;
  }
}

TEST_F(McapDamage, UnknownCompressionIsAnErrorNamingIt) {
  const fs::path file = write("zstd", "--compression zstd");
  std::string bytes = testing::read_text_file(file);
  const auto chunks = records_of(bytes, 0x06);
  // The compression name follows the start and end times, the size and the CRC.
  const std::size_t name = chunks[0].offset + 9 + 8 + 8 + 8 + 4 + 4;
  ASSERT_EQ(bytes.substr(name, 4), "zstd");
  bytes[name + 3] = 'x';
  for (const bool summary : {true, false}) {
    if (!summary) set_le64(bytes, bytes.size() - 8 - 20, 0);  // footer: summary_start = 0
    const fs::path damaged = altered("zstx.mcap", bytes);
    const std::string error = error_of([&] { testing::read_all(*open_mcap(damaged)); });
    EXPECT_NE(error.find("\"zstx\""), std::string::npos) << error;
    EXPECT_NE(error.find("the Chunk at offset " + std::to_string(chunks[0].offset)), std::string::npos) << error;
  }
}

TEST_F(McapDamage, SummaryPointingPastTheEndIsAnError) {
  const fs::path file = write("summary", "--compression lz4 --chunk-size 100000");
  const std::string bytes = testing::read_text_file(file);
  const std::size_t footer = bytes.size() - 8 - 29;
  ASSERT_EQ(bytes[footer], 0x02);
  {
    std::string b = bytes;
    set_le64(b, footer + 9, bytes.size() + 1000);  // summary_start
    const std::string error = error_of([&] { open_mcap(altered("past.mcap", b)); });
    EXPECT_NE(error.find("summary section starts at offset " + std::to_string(bytes.size() + 1000)), std::string::npos)
        << error;
  }
  {
    // A chunk index pointing past the end (the summary CRC cleared, so that it is this that is found).
    std::string b = bytes;
    const std::size_t summary = le64(b, footer + 9);
    b[footer + 9 + 16] = b[footer + 9 + 17] = b[footer + 9 + 18] = b[footer + 9 + 19] = 0;
    bool changed = false;
    for (const RecordAt& r : records_from(b, summary, footer))
      if (r.opcode == 0x08 && !changed) {
        set_le64(b, r.offset + 9 + 16, bytes.size() + 5);  // chunk_start_offset
        changed = true;
      }
    ASSERT_TRUE(changed);
    const std::string error = error_of([&] { open_mcap(altered("index_past.mcap", b)); });
    EXPECT_NE(error.find("points to a chunk at offset " + std::to_string(bytes.size() + 5)), std::string::npos) << error;
  }
  {
    std::string b = bytes;
    b[le64(b, footer + 9) + 12] ^= 1;  // inside the first summary record
    const std::string error = error_of([&] { open_mcap(altered("summary_crc.mcap", b)); });
    EXPECT_NE(error.find("does not match its CRC"), std::string::npos) << error;
  }
}

TEST_F(McapDamage, NotAnMcapFileIsAnErrorNamingIt) {
  EXPECT_NE(error_of([&] { open_mcap(altered("empty.mcap", "")); }).find("too short to be an MCAP file"),
            std::string::npos);
  const std::string bad_magic = error_of([&] { open_mcap(altered("text.mcap", std::string(100, 'x'))); });
  EXPECT_NE(bad_magic.find("does not start with the MCAP magic bytes"), std::string::npos) << bad_magic;
  EXPECT_NE(bad_magic.find("text.mcap"), std::string::npos) << bad_magic;
  EXPECT_NE(error_of([&] { open_mcap(dir()); }).find("not a regular file"), std::string::npos);
}

// Cut anywhere, or one byte changed anywhere: the reader reads, recovers with a note or throws
// Error; anything else (a crash, another exception) fails the test.
TEST_F(McapDamage, CutOrFlippedAnywhereIsNeverACrash) {
  // Without chunks there is no CRC: a changed byte in a message goes unseen, and a cut file is
  // read up to the cut. With zstd chunks, most changes are found.
  for (const auto& [options, some_errors] : {std::pair{"--compression zstd --chunk-size 100000", true},
                                             std::pair{"--profile ros1 --no-summary --unchunked", false}}) {
    const fs::path file = write("any", options);
    const std::string bytes = testing::read_text_file(file);
    int errors = 0, read = 0;
    auto attempt = [&](const std::string& content) {
      const fs::path damaged = altered("any_damaged.mcap", content);
      try {
        const auto reader = open_mcap(damaged);
        testing::read_all(*reader);
        ++read;
      } catch (const Error&) {
        ++errors;
      }
    };
    for (int i = 1; i < 60; ++i) attempt(bytes.substr(0, bytes.size() * static_cast<std::size_t>(i) / 60));
    std::mt19937 rng(7);
    for (int i = 0; i < 60; ++i) {
      std::string b = bytes;
      b[std::uniform_int_distribution<std::size_t>(0, b.size() - 1)(rng)] ^= static_cast<char>(1 + rng() % 255);
      attempt(b);
    }
    if (some_errors) {
      EXPECT_GT(errors, 0) << options;
    }
    EXPECT_GT(read, 0) << options;
  }
}

}  // namespace
}  // namespace slamvdb::recording
