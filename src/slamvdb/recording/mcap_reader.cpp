// Reading an MCAP file's messages in log-time order: chunks loaded (read, decompressed, CRC-checked)
// when the merge reaches their start time, their messages merged through a min-heap of cursors.
// No allocation per message: chunk buffers and cursors are reused.
#include <fmt/format.h>

#include <algorithm>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/crc32.hpp"
#include "slamvdb/recording/mcap_reader.hpp"

namespace slamvdb::recording::mcap {

namespace mcap_reader_cpp {

std::uint64_t u64_at(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return v;
}

// The first bytes of a Chunk record's content read to parse its fixed fields (the compression
// name is the only variable one, and short).
constexpr std::uint64_t kChunkHeadBytes = 4096;

[[noreturn]] void throw_short_message(const RecordPlace& at, std::uint64_t length) {
  throw Error(fmt::format("{} is {} bytes, shorter than a Message record's {} bytes of fixed fields: damaged",
                          at.describe(), length, kMessageFixedBytes));
}

}  // namespace mcap_reader_cpp
using namespace mcap_reader_cpp;

void McapReader::throw_bad_chunk_record(std::uint64_t chunk_offset, std::uint64_t pos, std::uint64_t left,
                                        std::uint8_t opcode) const {
  if (left < kRecordPrefix)
    throw Error(fmt::format("{}: the records of the Chunk at offset {} end inside a record prefix (byte {}): damaged",
                            file_.name(), chunk_offset, pos));
  throw Error(fmt::format("{}: the {} record at byte {} of the Chunk at offset {} extends past the chunk's records "
                          "({} bytes left): damaged",
                          file_.name(), opcode_name(opcode), pos, chunk_offset, left));
}

ChunkHeader McapReader::read_chunk_header(std::uint64_t offset, std::uint64_t length) {
  // The fixed fields and a short compression name in one small read; a longer name in a second.
  std::uint8_t head[kChunkHeadBytes];
  std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(length, 64));
  const std::string what = fmt::format("the Chunk record at offset {}", offset);
  file_.read_at(offset + kRecordPrefix, head, n, what);
  if (n >= 32) {
    const std::uint64_t name = head[28] | head[29] << 8 | head[30] << 16 | std::uint64_t{head[31]} << 24;
    const std::uint64_t wanted = std::min<std::uint64_t>({length, kChunkHeadBytes, 32 + name + 8});
    if (wanted > n) {
      n = static_cast<std::size_t>(wanted);
      file_.read_at(offset + kRecordPrefix, head, n, what);
    }
  }
  return parse_chunk_header({head, n}, length, place(kChunk, offset));
}

void McapReader::load_chunk(const ChunkHeader& header, std::uint64_t offset, ByteBuffer& records) {
  const std::string where = fmt::format("{}: the Chunk at offset {}", file_.name(), offset);
  if (header.uncompressed_size > SIZE_MAX / 2)
    throw Error(fmt::format("{} declares {} bytes of records: damaged", where, header.uncompressed_size));
  const auto size = static_cast<std::size_t>(header.uncompressed_size);
  if (header.compression.empty()) {
    if (header.records_size != header.uncompressed_size)
      throw Error(fmt::format("{} is uncompressed but says its records are {} bytes and holds {}: damaged", where,
                              header.uncompressed_size, header.records_size));
    records.resize(size, where);
    file_.read_at(header.records_offset, records.data(), size, where);  // the one copy of the data
  } else if (header.compression == "zstd" || header.compression == "lz4") {
    const bool zstd = header.compression == "zstd";
    if (!plausible_uncompressed_size(header.records_size, header.uncompressed_size, zstd ? kMaxZstdRatio : kMaxLz4Ratio))
      throw Error(fmt::format("{} says its {} bytes of {} data hold {} bytes, more than {} can: damaged", where,
                              header.records_size, header.compression, header.uncompressed_size, header.compression));
    compressed_.resize(static_cast<std::size_t>(header.records_size), where);
    file_.read_at(header.records_offset, compressed_.data(), compressed_.size(), where);
    records.resize(size, where);
    if (zstd)
      decompressor_.zstd_exact(compressed_.span(), records.span(), where);
    else
      decompressor_.lz4_frame_exact(compressed_.span(), records.span(), where, header.uncompressed_crc == 0);
  } else {
    throw Error(fmt::format("{} uses the compression \"{}\", which this reader does not know (it reads zstd, lz4 and "
                            "uncompressed chunks)",
                            where, header.compression));
  }
  if (header.uncompressed_crc != 0) {
    const std::uint32_t crc = crc32(0, records.data(), records.size());
    if (crc != header.uncompressed_crc)
      throw Error(fmt::format("{}: its records do not match the chunk's CRC (computed {:08x}, the chunk says {:08x}): "
                              "damaged",
                              where, crc, header.uncompressed_crc));
  }
}

void McapReader::fill_entries(Cursor& cursor, std::uint64_t chunk_offset) {
  cursor.entries.clear();
  cursor.next = 0;
  bool sorted = true;
  std::uint64_t previous = 0;
  const std::uint8_t* base = cursor.records.data();
  walk_records(cursor.records.span(), chunk_offset,
               [&](std::uint8_t opcode, std::span<const std::uint8_t> content, const RecordPlace& at) {
                 if (opcode != kMessage) return;  // Schema and Channel records are known already
                 if (content.size() < kMessageFixedBytes) throw_short_message(at, content.size());
                 const std::uint16_t channel = static_cast<std::uint16_t>(content[0] | (content[1] << 8));
                 const std::uint64_t log_time = u64_at(content.data() + 6);
                 if (channel_index(channel) < 0)
                   throw Error(fmt::format("{} is on channel {}, which no Channel record defines: damaged",
                                           at.describe(), channel));
                 if (log_time > static_cast<std::uint64_t>(INT64_MAX))
                   throw Error(fmt::format("{} has the log time {} ns, beyond the year 2262: damaged", at.describe(),
                                           log_time));
                 if (!selected(channel)) return;
                 sorted = sorted && log_time >= previous;
                 previous = log_time;
                 cursor.entries.push_back(Entry{log_time,
                                                static_cast<std::uint64_t>(content.data() - base) + kMessageFixedBytes,
                                                content.size() - kMessageFixedBytes, channel});
               });
  if (!sorted)
    std::stable_sort(cursor.entries.begin(), cursor.entries.end(),
                     [](const Entry& a, const Entry& b) { return a.log_time < b.log_time; });
}

std::unique_ptr<McapReader::Cursor> McapReader::take_cursor() {
  if (spare_.empty()) return std::make_unique<Cursor>();
  std::unique_ptr<Cursor> cursor = std::move(spare_.back());
  spare_.pop_back();
  cursor->entries.clear();
  cursor->next = 0;
  return cursor;
}

namespace mcap_reader_cpp {
// Heap order: the cursor whose next message is earliest (log time, then file order) on top.
struct CursorAfter {
  template <typename C>
  bool operator()(const C& a, const C& b) const {
    const auto& x = a->entries[a->next];
    const auto& y = b->entries[b->next];
    if (x.log_time != y.log_time) return x.log_time > y.log_time;
    if (a->file_offset != b->file_offset) return a->file_offset > b->file_offset;
    return x.data_offset > y.data_offset;
  }
};
}  // namespace mcap_reader_cpp
using namespace mcap_reader_cpp;

bool McapReader::peek_linear() {
  if (peek_) return true;
  while (!linear_done_ && linear_pos_ < data_end_) {
    std::uint8_t opcode = 0;
    std::uint64_t length = 0;
    if (!record_is_whole(linear_pos_, opcode, length) || opcode == kDataEnd || opcode == kFooter) break;
    LinearPeek p;
    p.opcode = opcode;
    p.offset = linear_pos_;
    p.length = length;
    if (opcode == kChunk) {
      p.chunk = read_chunk_header(linear_pos_, length);
      p.start_time = p.chunk.message_start_time;
      peek_ = std::move(p);
      return true;
    }
    if (opcode == kMessage) {
      std::uint8_t fixed[kMessageFixedBytes];
      const RecordPlace at = place(kMessage, linear_pos_);
      if (length < kMessageFixedBytes) throw_short_message(at, length);
      file_.read_at(linear_pos_ + kRecordPrefix, fixed, sizeof fixed, at.describe());
      const MessageView m = parse_message(fixed, at);
      if (channel_index(m.channel_id) < 0)
        throw Error(fmt::format("{} is on channel {}, which no Channel record defines: damaged", at.describe(),
                                m.channel_id));
      if (m.log_time > static_cast<std::uint64_t>(INT64_MAX))
        throw Error(fmt::format("{} has the log time {} ns, beyond the year 2262: damaged", at.describe(), m.log_time));
      if (selected(m.channel_id)) {
        p.start_time = m.log_time;
        peek_ = std::move(p);
        return true;
      }
    }
    // Schema and Channel records (known from the summary or the first pass), indexes,
    // attachments, metadata, private records: nothing to deliver.
    linear_pos_ += kRecordPrefix + length;
  }
  linear_done_ = true;
  return false;
}

bool McapReader::more_sources() {
  return indexed_ ? next_chunk_ < chunk_indexes_.size() : peek_linear();
}

bool McapReader::chunk_selected(const ChunkIndexRecord& index) const {
  // Without a channel list the chunk must be read; with one, only if it holds a selected channel.
  if (all_selected_ || index.channels.empty()) return true;
  return std::any_of(index.channels.begin(), index.channels.end(), [&](std::uint16_t c) { return selected(c); });
}

std::uint64_t McapReader::next_source_time() const {
  return indexed_ ? chunk_indexes_[next_chunk_].message_start_time : peek_->start_time;
}

void McapReader::open_next_source() {
  std::unique_ptr<Cursor> cursor = take_cursor();
  if (indexed_) {
    const ChunkIndexRecord& index = chunk_indexes_[next_chunk_++];
    if (!chunk_selected(index)) {  // skipped unread, when the merge reaches its start time
      ++chunks_skipped_;
      spare_.push_back(std::move(cursor));
      return;
    }
    std::uint8_t prefix[kRecordPrefix];
    file_.read_at(index.chunk_start_offset, prefix, sizeof prefix, "a Chunk record's opcode and length");
    if (prefix[0] != kChunk || u64_at(prefix + 1) != index.chunk_length - kRecordPrefix)
      throw Error(fmt::format("{}: the chunk index points to a Chunk record of {} bytes at offset {}, but the record "
                              "there is a {} record of {} bytes: damaged",
                              file_.name(), index.chunk_length, index.chunk_start_offset, opcode_name(prefix[0]),
                              u64_at(prefix + 1) + kRecordPrefix));
    const ChunkHeader header = read_chunk_header(index.chunk_start_offset, index.chunk_length - kRecordPrefix);
    load_chunk(header, index.chunk_start_offset, cursor->records);
    cursor->file_offset = index.chunk_start_offset;
    fill_entries(*cursor, index.chunk_start_offset);
  } else {
    const LinearPeek p = std::move(*peek_);
    peek_.reset();
    linear_pos_ = p.offset + kRecordPrefix + p.length;
    cursor->file_offset = p.offset;
    if (p.opcode == kChunk) {
      load_chunk(p.chunk, p.offset, cursor->records);
      fill_entries(*cursor, p.offset);
    } else {  // a Message record outside chunks
      const std::string where = place(kMessage, p.offset).describe();
      cursor->records.resize(static_cast<std::size_t>(p.length), where);
      file_.read_at(p.offset + kRecordPrefix, cursor->records.data(), cursor->records.size(), where);
      cursor->entries.push_back(Entry{p.start_time, kMessageFixedBytes, p.length - kMessageFixedBytes,
                                      static_cast<std::uint16_t>(cursor->records.data()[0] |
                                                                 (cursor->records.data()[1] << 8))});
    }
  }
  if (cursor->entries.empty()) {
    spare_.push_back(std::move(cursor));
    return;
  }
  heap_.push_back(std::move(cursor));
  std::push_heap(heap_.begin(), heap_.end(), CursorAfter{});
  max_open_ = std::max(max_open_, heap_.size() + (current_ ? 1 : 0));
}

bool McapReader::next(Message& out) {
  while (true) {
    if (current_) {  // the message handed out last is no longer needed
      auto& entries = current_->entries;
      ++current_->next;
      while (current_->next < entries.size() && !selected(entries[current_->next].channel)) ++current_->next;
      if (current_->next < entries.size()) {
        heap_.push_back(std::move(current_));
        std::push_heap(heap_.begin(), heap_.end(), CursorAfter{});
      } else {
        spare_.push_back(std::move(current_));
      }
      current_.reset();
    }
    while (more_sources() &&
           (heap_.empty() || next_source_time() <= heap_.front()->entries[heap_.front()->next].log_time))
      open_next_source();
    if (heap_.empty()) {
      finished_ = true;
      return false;
    }
    std::pop_heap(heap_.begin(), heap_.end(), CursorAfter{});
    current_ = std::move(heap_.back());
    heap_.pop_back();
    const Entry& entry = current_->entries[current_->next];
    if (!selected(entry.channel)) continue;  // deselected after its chunk was opened
    out.channel = &channels_[static_cast<std::size_t>(channel_index(entry.channel))];
    out.log_time_ns = static_cast<std::int64_t>(entry.log_time);
    out.data = {current_->records.data() + entry.data_offset, static_cast<std::size_t>(entry.data_size)};
    out.index = delivered_++;
    if (entry.log_time < last_time_) ++out_of_order_;
    last_time_ = entry.log_time;
    return true;
  }
}

void McapReader::select(const std::set<std::uint32_t>& channel_ids) {
  all_selected_ = channel_ids.empty();
  std::fill(selected_.begin(), selected_.end(), all_selected_ ? 1 : 0);
  for (const std::uint32_t id : channel_ids)
    if (id < selected_.size()) selected_[id] = 1;
  if (!all_selected_) selection_changed_ = true;
}

}  // namespace slamvdb::recording::mcap
