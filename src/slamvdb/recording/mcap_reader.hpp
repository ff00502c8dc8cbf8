#pragma once
// The MCAP reader's class (mcap.hpp is the interface): opening (mcap_open.cpp: magic, footer,
// summary, or a first pass over a file without one) and reading (mcap_reader.cpp: chunks merged in
// log-time order).
//
// Reading order. Messages come out in log-time order, equal times in file order, whatever order
// the chunks are in: chunks are opened in order of their first message's time (from the chunk
// index, or from each chunk's header when reading linearly), and an open chunk's messages are merged
// with the other open chunks' (a min-heap of cursors, one per open chunk). A chunk is opened only
// when the merge reaches its start time, so memory is bounded by the chunks whose time ranges
// overlap (one or two for a recorder writing in time order). Linear reading can only reorder what
// overlaps neighbouring chunks; a message that still comes out earlier than the one before is
// counted and said in notes().
//
// CRCs: a chunk's uncompressed_crc is checked (when not zero) every time the chunk is read; the
// summary's CRC (footer summary_crc) when the summary is read. The Data End record's
// data_section_crc is not: it covers the whole data section, attachments included, which indexed
// reading never reads, and every message byte in a chunk is covered by the chunk's CRC.
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "slamvdb/recording/decompress.hpp"
#include "slamvdb/recording/mcap_records.hpp"
#include "slamvdb/recording/positional_file.hpp"
#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording::mcap {

class McapReader final : public RecordingReader {
 public:
  explicit McapReader(const std::filesystem::path& path);

  std::string describe() const override;
  const std::vector<Channel>& channels() const override { return channels_; }
  std::optional<TimeRange> time_range() const override { return range_; }
  std::uint64_t size_bytes() const override { return file_.size(); }
  void select(const std::set<std::uint32_t>& channel_ids) override;
  bool next(Message& out) override;
  std::uint64_t bytes_read() const override { return file_.bytes_read(); }
  std::vector<std::string> notes() const override;

 private:
  // One message of an open chunk, in the chunk's uncompressed records.
  struct Entry {
    std::uint64_t log_time = 0;
    std::uint64_t data_offset = 0, data_size = 0;
    std::uint16_t channel = 0;
  };
  // An open chunk (or a single Message record outside chunks) being merged.
  struct Cursor {
    std::uint64_t file_offset = 0;  // of its record: orders equal times
    ByteBuffer records;
    std::vector<Entry> entries;  // messages of selected channels, sorted by (log time, offset)
    std::size_t next = 0;
  };
  // The record the linear reading stands at.
  struct LinearPeek {
    std::uint8_t opcode = 0;
    std::uint64_t offset = 0, length = 0;
    std::uint64_t start_time = 0;
    ChunkHeader chunk;  // when opcode == kChunk
  };

  // mcap_open.cpp
  void read_footer_and_summary();
  void read_summary(const FooterRecord& footer, std::uint64_t footer_offset);
  // Whether the record at `pos` (before data_end_) is whole; when it is not, a file without a footer
  // was cut short (a note; reading stops there) and one with a footer is damaged (an Error).
  bool record_is_whole(std::uint64_t pos, std::uint8_t& opcode, std::uint64_t& length);
  void scan_channels();  // the first pass over a file without a summary
  void add_schema(SchemaRecord schema);
  void add_channel(const ChannelRecord& channel, const RecordPlace& place);
  void build_channels();
  RecordPlace place(std::uint8_t opcode, std::uint64_t offset) const;

  // mcap_reader.cpp
  ChunkHeader read_chunk_header(std::uint64_t offset, std::uint64_t length);
  // Decompresses and checks a chunk into `records`.
  void load_chunk(const ChunkHeader& header, std::uint64_t offset, ByteBuffer& records);
  // Calls visit(opcode, content, place) for every record of a chunk's (uncompressed) records.
  template <typename Visit>
  void walk_records(std::span<const std::uint8_t> records, std::uint64_t chunk_offset, Visit&& visit) const {
    for (std::uint64_t pos = 0; pos < records.size();) {
      const std::uint64_t left = records.size() - pos;
      if (left < kRecordPrefix) throw_bad_chunk_record(chunk_offset, pos, left, 0);
      std::uint64_t length = 0;
      for (int i = 0; i < 8; ++i) length |= static_cast<std::uint64_t>(records[pos + 1 + i]) << (8 * i);
      if (length > left - kRecordPrefix) throw_bad_chunk_record(chunk_offset, pos, left, records[pos]);
      const RecordPlace at{file_.name(), records[pos], pos, chunk_offset};
      visit(records[pos], records.subspan(pos + kRecordPrefix, length), at);
      pos += kRecordPrefix + length;
    }
  }
  [[noreturn]] void throw_bad_chunk_record(std::uint64_t chunk_offset, std::uint64_t pos, std::uint64_t left,
                                           std::uint8_t opcode) const;
  void fill_entries(Cursor& cursor, std::uint64_t chunk_offset);
  // Linear reading: the record at linear_pos_ (skipping the ones that hold no messages); false at
  // the end of the data section (or where a truncated file ends, with a note).
  bool peek_linear();
  bool more_sources();
  bool chunk_selected(const ChunkIndexRecord& index) const;
  std::uint64_t next_source_time() const;
  void open_next_source();
  std::unique_ptr<Cursor> take_cursor();
  bool selected(std::uint16_t channel) const { return selected_[channel] != 0; }
  int channel_index(std::uint16_t id) const { return channel_index_[id]; }

  PositionalFile file_;
  std::string profile_;
  std::uint64_t data_start_ = 0;  // the first record after the Header
  std::uint64_t data_end_ = 0;    // where linear reading stops
  bool has_footer_ = false, has_summary_ = false, indexed_ = false, scanned_ = false;
  std::map<std::uint16_t, SchemaRecord> schemas_;
  std::map<std::uint16_t, ChannelRecord> channel_records_;
  std::vector<Channel> channels_;
  std::vector<int> channel_index_;  // MCAP channel id -> index in channels_ (-1: none)
  std::map<std::uint16_t, std::uint64_t> counts_;  // from the statistics or the first pass
  std::optional<TimeRange> range_;
  std::optional<std::uint64_t> statistics_messages_;
  std::vector<ChunkIndexRecord> chunk_indexes_;  // sorted by (start time, offset)
  std::set<std::string> compressions_;
  std::uint64_t chunk_count_ = 0;
  std::vector<std::string> notes_;
  bool truncated_noted_ = false;

  // Reading.
  std::vector<char> selected_;
  bool selection_changed_ = false, all_selected_ = true;
  Decompressor decompressor_;
  ByteBuffer compressed_;
  std::vector<std::unique_ptr<Cursor>> heap_;  // min-heap (see cursor_after)
  std::vector<std::unique_ptr<Cursor>> spare_;
  std::unique_ptr<Cursor> current_;  // holds the message handed out last
  std::size_t next_chunk_ = 0;
  std::uint64_t linear_pos_ = 0;
  std::optional<LinearPeek> peek_;
  bool linear_done_ = false;
  std::uint64_t delivered_ = 0, out_of_order_ = 0, last_time_ = 0, chunks_skipped_ = 0;
  std::size_t max_open_ = 0;
  bool finished_ = false;
};

}  // namespace slamvdb::recording::mcap
