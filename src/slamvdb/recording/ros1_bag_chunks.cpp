// The ROS 1 bag reader's records and chunks, and the linear reading of a bag without index.
#include <fmt/format.h>

#include <algorithm>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/decompress.hpp"
#include "slamvdb/recording/ros1_bag_reader.hpp"

namespace slamvdb::recording::ros1 {

namespace chunks_detail {

// An unfinished chunk's data are read up to this much (rosbag's chunks are 768 kB by default).
constexpr std::uint64_t kMaxUnfinishedChunkBytes = std::uint64_t{256} << 20;
// The most an unfinished chunk is allowed to decompress to.
constexpr std::size_t kMaxUnfinishedChunkOutput = std::size_t{1} << 30;

std::uint32_t bag_u32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[3]} << 24;
}

}  // namespace chunks_detail

std::optional<FileRecord> Ros1BagReader::read_record(std::uint64_t offset, std::string& why) {
  const std::uint64_t size = file_.size();
  if (offset > size || size - offset < 8) {
    why = fmt::format("{} bytes left, too few for a record", offset > size ? 0 : size - offset);
    return std::nullopt;
  }
  std::uint8_t length[4];
  file_.read_at(offset, length, 4, "a record's header length");
  const std::uint32_t header_length = chunks_detail::bag_u32(length);
  if (header_length > kMaxRecordHeaderBytes) {
    why = fmt::format("a record header of {} bytes (damaged: real ones have a few dozen)", header_length);
    return std::nullopt;
  }
  if (std::uint64_t{header_length} + 8 > size - offset) {
    why = fmt::format("a record header of {} bytes with {} bytes left in the file", header_length, size - offset - 4);
    return std::nullopt;
  }
  FileRecord record;
  record.offset = offset;
  record.header.resize(header_length);
  file_.read_at(offset + 4, record.header.data(), header_length, "a record header");
  file_.read_at(offset + 4 + header_length, length, 4, "a record's data length");
  record.data_length = chunks_detail::bag_u32(length);
  record.data_offset = offset + 8 + header_length;
  return record;  // its data may run past the end of the file: the callers decide
}

RecordFields Ros1BagReader::fields_of(const FileRecord& record) const {
  try {
    return RecordFields(record.header);
  } catch (const Error& e) {
    fail(record.offset, e.what());
  }
}

std::string Ros1BagReader::load_chunk(const FileRecord& record, OpenChunk& chunk, bool salvage, bool unfinished) {
  const RecordFields fields = fields_of(record);
  std::string compression;
  std::uint32_t size = 0;
  try {
    if (fields.op() != static_cast<std::uint8_t>(Op::kChunk))
      throw Error(fmt::format("a {} record where a chunk should be", op_name(fields.op())));
    compression = fields.string("compression");
    size = fields.u32("size");
  } catch (const Error& e) {
    fail(record.offset, e.what());
  }
  const std::uint64_t left = file_.size() - std::min(file_.size(), record.data_offset);
  const std::uint64_t available = std::min<std::uint64_t>(record.data_length, left);
  std::string loss;
  if (available < record.data_length) {
    if (!salvage)
      fail(record.offset, fmt::format("the chunk's {} bytes run past the end of the file ({} bytes left): the file is "
                                      "cut short",
                                      record.data_length, left));
    loss = fmt::format("its last {} bytes are missing", record.data_length - available);
  }
  if (compression != "none" && compression != "bz2" && compression != "lz4")
    fail(record.offset, fmt::format("unknown chunk compression \"{}\" (a ROS 1 bag chunk is none, bz2 or lz4)",
                                    compression));
  compressions_.insert(compression);
  if (compression == "none") {
    chunk.data.resize(available);
    file_.read_at(record.data_offset, chunk.data.data(), chunk.data.size(), "a chunk's data");
    if (loss.empty() && size != record.data_length)
      fail(record.offset, fmt::format("an uncompressed chunk of {} bytes records its size as {}", record.data_length,
                                      size));
    return loss;
  }
  compressed_.resize(available);
  file_.read_at(record.data_offset, compressed_.data(), compressed_.size(), "a chunk's data");
  const std::size_t max_size = unfinished ? chunks_detail::kMaxUnfinishedChunkOutput : size;
  const Decompressed result = compression == "lz4"
                                  ? decompressor_.lz4_frame_recover(compressed_, max_size, chunk.data)
                                  : decompress_bz2(compressed_, max_size, chunk.data);
  if (compressed_.capacity() > (std::size_t{64} << 20)) compressed_ = {};  // no big buffer kept for a rare chunk
  if (result.complete) return loss;
  if (!salvage) fail(record.offset, fmt::format("the chunk's {} data are damaged: {}", compression, result.problem));
  return loss.empty() ? result.problem : loss;
}

std::string Ros1BagReader::scan_chunk(OpenChunk& chunk, bool salvage) {
  chunk.entries.clear();
  chunk.next = 0;
  const std::span<const std::uint8_t> data(chunk.data);
  std::size_t offset = 0;
  std::string stopped;
  while (offset < data.size()) {
    const auto record = record_at(data, offset, stopped);
    if (!record) break;
    try {
      const RecordFields fields(record->header);
      const std::uint8_t op = fields.op();
      if (op == static_cast<std::uint8_t>(Op::kConnection)) {
        add_channel(parse_connection(fields, record->data));
      } else if (op == static_cast<std::uint8_t>(Op::kMessageData)) {
        const std::uint32_t connection = fields.u32("conn");
        if (!channel_of_connection_.count(connection))
          throw Error(fmt::format("a message on connection {}, which no connection record describes", connection));
        chunk.entries.push_back({fields.time_ns("time"), connection, static_cast<std::uint32_t>(record->data.size()),
                                 record->end - record->data.size()});
      } else {
        throw Error(fmt::format("a {} record (op {:#04x}) inside a chunk", op_name(op), op));
      }
    } catch (const Error& e) {
      stopped = e.what();
      break;
    }
    offset = record->end;
  }
  if (offset < data.size()) {
    if (!salvage)
      fail(chunk.file_offset, fmt::format("inside the chunk, at byte {} of {}: {}", offset, data.size(), stopped));
  } else {
    stopped.clear();
  }
  std::stable_sort(chunk.entries.begin(), chunk.entries.end(),
                   [](const ChunkEntry& a, const ChunkEntry& b) { return a.time_ns < b.time_ns; });
  return stopped;
}

bool Ros1BagReader::next_linear(Message& out) {
  while (true) {
    while (current_.next < current_.entries.size()) {
      const ChunkEntry& entry = current_.entries[current_.next++];
      if (!wanted(entry.connection)) continue;
      emit(current_, entry, out);
      return true;
    }
    if (linear_done_) return false;
    advance_linear();
  }
}

void Ros1BagReader::advance_linear() {
  current_.entries.clear();
  current_.next = 0;
  const std::uint64_t offset = linear_offset_;
  if (offset >= file_.size()) {
    linear_done_ = true;
    return;
  }
  const auto stop = [&](const std::string& why) {
    note(fmt::format("reading stopped at offset {} of {}: {}; the {} messages before it were read", offset,
                     file_.size(), why, message_index_));
    linear_done_ = true;
  };
  std::string why;
  const auto record = read_record(offset, why);
  if (!record) return stop(why + " (a recording cut short?)");
  std::uint8_t op = 0;
  std::string compression;
  std::uint32_t size = 0;
  try {
    const RecordFields fields(record->header);
    op = fields.op();
    if (op == static_cast<std::uint8_t>(Op::kChunk)) {
      compression = fields.string("compression");
      size = fields.u32("size");
    }
  } catch (const Error& e) {
    return stop(fmt::format("a damaged record ({})", e.what()));
  }
  const bool cut = record->end() > file_.size();
  linear_offset_ = record->end();
  current_.file_offset = offset;
  if (op == static_cast<std::uint8_t>(Op::kChunk)) {
    const bool placeholder = record->data_length == 0 && size == 0;
    if (placeholder && compression == "none") {
      note(fmt::format("an unfinished uncompressed chunk at offset {}: its records were read one by one", offset));
      return;
    }
    if (placeholder) {
      // The recorder was stopped while writing this chunk: its compressed data run to the end of
      // the file, as far as they were written.
      FileRecord rest = *record;
      rest.data_length = static_cast<std::uint32_t>(
          std::min(file_.size() - record->data_offset, chunks_detail::kMaxUnfinishedChunkBytes));
      const std::string loss = load_chunk(rest, current_, true, true);
      const std::string stopped = scan_chunk(current_, true);
      note(fmt::format("an unfinished {} chunk at offset {} (the recorder was stopped while writing it): {} messages "
                       "recovered, the rest lost ({})",
                       compression, offset, current_.entries.size(), stopped.empty() ? loss : stopped));
      linear_done_ = true;
      return;
    }
    const std::string loss = load_chunk(*record, current_, cut);
    const std::string stopped = scan_chunk(current_, cut);
    if (cut) {
      note(fmt::format("the chunk at offset {} is cut short by the end of the file: {} of its messages recovered, the "
                       "rest lost ({})",
                       offset, current_.entries.size(), loss.empty() ? stopped : loss));
      linear_done_ = true;
    }
    return;
  }
  if (op == static_cast<std::uint8_t>(Op::kBagHeader) || op == static_cast<std::uint8_t>(Op::kIndexData) ||
      op == static_cast<std::uint8_t>(Op::kChunkInfo))
    return;  // index records (of chunks read already) and the header: nothing to read
  if (op != static_cast<std::uint8_t>(Op::kConnection) && op != static_cast<std::uint8_t>(Op::kMessageData)) {
    note(fmt::format("a record of unknown op {:#04x} at offset {} was skipped", op, offset));
    return;
  }
  if (cut) return stop(fmt::format("the file ends inside a {} record", op_name(op)));
  // A connection or message outside any chunk: an unfinished uncompressed chunk's records.
  current_.data.resize(record->data_length);
  file_.read_at(record->data_offset, current_.data.data(), current_.data.size(), "a record's data");
  try {
    const RecordFields fields(record->header);
    if (op == static_cast<std::uint8_t>(Op::kConnection)) {
      add_channel(parse_connection(fields, current_.data));
      return;
    }
    const std::uint32_t connection = fields.u32("conn");
    if (!channel_of_connection_.count(connection))
      throw Error(fmt::format("a message on connection {}, which no connection record describes", connection));
    current_.entries.push_back({fields.time_ns("time"), connection, record->data_length, 0});
  } catch (const Error& e) {
    fail(offset, e.what());
  }
}

}  // namespace slamvdb::recording::ros1
