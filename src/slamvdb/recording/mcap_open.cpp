// Opening an MCAP file: magic and Header, then the Footer and the summary section when the file
// has them; a file without a summary (or whose summary lists no channels) is scanned once, chunk by
// chunk, for its Schema and Channel records, message counts and time range.
#include <fmt/format.h>

#include <algorithm>
#include <cstring>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/crc32.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/recording/mcap_reader.hpp"

namespace slamvdb::recording {

std::unique_ptr<RecordingReader> open_mcap(const std::filesystem::path& path) {
  return std::make_unique<mcap::McapReader>(path);
}

namespace mcap {

namespace mcap_open_cpp {

std::uint64_t read_u64_le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return v;
}

// Records a reader keeps whole in memory (Header, Schema, Channel, the summary section) are small in
// any real file; a larger one is damage.
constexpr std::uint64_t kMaxSmallRecord = std::uint64_t{1} << 30;

Serialization serialization_of(const std::string& message_encoding) {
  if (message_encoding == "ros1") return Serialization::kRos1;
  if (message_encoding == "cdr") return Serialization::kCdr;
  return Serialization::kOther;
}

}  // namespace mcap_open_cpp
using namespace mcap_open_cpp;

RecordPlace McapReader::place(std::uint8_t opcode, std::uint64_t offset) const {
  return RecordPlace{file_.name(), opcode, offset};
}

McapReader::McapReader(const std::filesystem::path& path)
    : file_(path, "MCAP file"), channel_index_(65536, -1), selected_(65536, 1) {
  std::uint8_t head[sizeof kMagic + kRecordPrefix];
  if (file_.size() < sizeof head)
    throw Error(fmt::format("{} is {} bytes, too short to be an MCAP file", file_.name(), file_.size()));
  file_.read_at(0, head, sizeof head, "the magic bytes and the Header record");
  if (std::memcmp(head, kMagic, sizeof kMagic) != 0)
    throw Error(fmt::format("{} does not start with the MCAP magic bytes (89 4D 43 41 50 30 0D 0A)", file_.name()));
  const std::uint64_t header_length = read_u64_le(head + sizeof kMagic + 1);
  if (head[sizeof kMagic] != kHeader || header_length > kMaxSmallRecord ||
      !file_.contains(sizeof head, header_length))
    throw Error(fmt::format("{}: the first record (offset 8) is not a whole Header record", file_.name()));
  std::vector<std::uint8_t> header(static_cast<std::size_t>(header_length));
  file_.read_at(sizeof head, header.data(), header.size(), "the Header record");
  profile_ = parse_header_profile(header, place(kHeader, sizeof kMagic));
  data_start_ = sizeof head + header_length;
  linear_pos_ = data_start_;

  read_footer_and_summary();
  if (channel_records_.empty()) {
    if (has_summary_)
      notes_.push_back(fmt::format("{}: the summary section lists no channels: the file was scanned once for them",
                                   file_.name()));
    counts_.clear();
    scan_channels();
  }
  build_channels();
}

void McapReader::read_footer_and_summary() {
  const std::uint64_t size = file_.size();
  std::uint64_t footer_offset = 0;
  FooterRecord footer;
  if (size >= data_start_ + kFooterAndMagic) {
    std::uint8_t tail[kFooterAndMagic];
    footer_offset = size - kFooterAndMagic;
    file_.read_at(footer_offset, tail, sizeof tail, "the Footer record and the trailing magic bytes");
    if (std::memcmp(tail + kRecordPrefix + kFooterContent, kMagic, sizeof kMagic) == 0) {
      if (tail[0] != kFooter || read_u64_le(tail + 1) != kFooterContent)
        throw Error(fmt::format("{}: the file ends with the MCAP magic bytes but the 29 bytes before them (offset "
                                "{}) are not a Footer record: damaged",
                                file_.name(), footer_offset));
      footer = parse_footer({tail + kRecordPrefix, kFooterContent}, place(kFooter, footer_offset));
      has_footer_ = true;
    }
  }
  if (!has_footer_) {
    data_end_ = size;
    notes_.push_back(fmt::format(
        "{} has no footer (the recording was not closed: still being written, or cut short): it was scanned once "
        "for its channels and is read linearly",
        file_.name()));
    return;
  }
  data_end_ = footer_offset;
  if (footer.summary_start == 0) {
    notes_.push_back(fmt::format(
        "{} has no summary section (no index): it was scanned once for its channels and is read linearly",
        file_.name()));
    return;
  }
  read_summary(footer, footer_offset);
}

void McapReader::read_summary(const FooterRecord& footer, std::uint64_t footer_offset) {
  const std::uint64_t start = footer.summary_start;
  if (start < data_start_ || start >= footer_offset)
    throw Error(fmt::format("{}: the footer says the summary section starts at offset {}, outside the data between "
                            "the Header and the Footer (offsets {} to {}): damaged",
                            file_.name(), start, data_start_, footer_offset));
  const std::uint64_t end = footer.summary_offset_start != 0 ? footer.summary_offset_start : footer_offset;
  if (end < start || end > footer_offset)
    throw Error(fmt::format("{}: the footer says the summary offsets start at offset {}, outside the summary (offsets "
                            "{} to {}): damaged",
                            file_.name(), end, start, footer_offset));
  // The summary CRC covers the summary, the summary offsets and the footer up to its CRC field.
  const std::uint64_t covered = footer_offset + kRecordPrefix + 16 - start;
  if (covered > kMaxSmallRecord)
    throw Error(fmt::format("{}: the summary section is {} bytes, more than a summary can sensibly be", file_.name(),
                            covered));
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(covered));
  file_.read_at(start, bytes.data(), bytes.size(), "the summary section");
  if (footer.summary_crc != 0) {
    const std::uint32_t crc = crc32(0, bytes.data(), bytes.size());
    if (crc != footer.summary_crc)
      throw Error(fmt::format("{}: the summary section (offset {}) does not match its CRC (computed {:08x}, the footer "
                              "says {:08x}): damaged",
                              file_.name(), start, crc, footer.summary_crc));
  }
  std::optional<StatisticsRecord> statistics;
  for (std::uint64_t pos = 0; pos < end - start;) {
    const std::uint64_t offset = start + pos;
    if (end - start - pos < kRecordPrefix)
      throw Error(fmt::format("{}: the summary section ends inside a record prefix at offset {}", file_.name(), offset));
    const std::uint8_t opcode = bytes[pos];
    const std::uint64_t length = read_u64_le(&bytes[pos + 1]);
    if (length > end - start - pos - kRecordPrefix)
      throw Error(fmt::format("{}: the {} record at offset {} is {} bytes, past the end of the summary section "
                              "(offset {}): damaged",
                              file_.name(), opcode_name(opcode), offset, length, end));
    const std::span<const std::uint8_t> content(&bytes[pos + kRecordPrefix], static_cast<std::size_t>(length));
    const RecordPlace where = place(opcode, offset);
    if (opcode == kSchema) {
      add_schema(parse_schema(content, where));
    } else if (opcode == kChannel) {
      add_channel(parse_channel(content, where), where);
    } else if (opcode == kChunkIndex) {
      ChunkIndexRecord index = parse_chunk_index(content, where);
      if (index.chunk_start_offset < data_start_ || index.chunk_length < kRecordPrefix ||
          index.chunk_start_offset > start || index.chunk_length > start - index.chunk_start_offset)
        throw Error(fmt::format("{}: the Chunk Index record at offset {} points to a chunk at offset {} of {} bytes, "
                                "outside the data section (offsets {} to {}): damaged",
                                file_.name(), offset, index.chunk_start_offset, index.chunk_length, data_start_,
                                start));
      chunk_indexes_.push_back(std::move(index));
    } else if (opcode == kStatistics) {
      statistics = parse_statistics(content, where);
    }
    pos += kRecordPrefix + length;
  }
  has_summary_ = true;
  data_end_ = start;
  indexed_ = !chunk_indexes_.empty();
  std::sort(chunk_indexes_.begin(), chunk_indexes_.end(), [](const auto& a, const auto& b) {
    return a.message_start_time != b.message_start_time ? a.message_start_time < b.message_start_time
                                                        : a.chunk_start_offset < b.chunk_start_offset;
  });
  for (const auto& index : chunk_indexes_) compressions_.insert(index.compression);
  chunk_count_ = chunk_indexes_.size();
  if (statistics) {
    statistics_messages_ = statistics->message_count;
    for (const auto& [channel, count] : statistics->channel_message_counts) counts_[channel] = count;
    if (statistics->message_count > 0)
      range_ = TimeRange{static_cast<std::int64_t>(statistics->message_start_time),
                         static_cast<std::int64_t>(statistics->message_end_time)};
  } else if (indexed_) {
    std::uint64_t first = UINT64_MAX, last = 0;
    for (const auto& index : chunk_indexes_) {
      first = std::min(first, index.message_start_time);
      last = std::max(last, index.message_end_time);
    }
    range_ = TimeRange{static_cast<std::int64_t>(first), static_cast<std::int64_t>(last)};
  }
  if (!indexed_)
    notes_.push_back(fmt::format("{} has a summary but no chunk index: it is read linearly", file_.name()));
}

bool McapReader::record_is_whole(std::uint64_t pos, std::uint8_t& opcode, std::uint64_t& length) {
  std::uint8_t prefix[kRecordPrefix];
  const std::uint64_t left = data_end_ - pos;
  if (left >= kRecordPrefix) {
    file_.read_at(pos, prefix, sizeof prefix, "a record's opcode and length");
    opcode = prefix[0];
    length = read_u64_le(prefix + 1);
    if (length <= left - kRecordPrefix) return true;
  }
  const std::string what = left >= kRecordPrefix ? fmt::format("the {} record", opcode_name(opcode))
                                                 : std::string("a record's opcode and length");
  if (has_footer_)
    throw Error(fmt::format("{}: {} at offset {} extends past the end of the data section (offset {}): damaged",
                            file_.name(), what, pos, data_end_));
  if (!truncated_noted_)
    notes_.push_back(fmt::format("{} ends inside {} at offset {} (cut short, or still being written): the {} bytes from "
                                 "there on are not read",
                                 file_.name(), what, pos, left));
  truncated_noted_ = true;
  data_end_ = pos;  // the main pass stops here too
  return false;
}

void McapReader::scan_channels() {
  scanned_ = true;
  ByteBuffer records;
  std::uint64_t first = UINT64_MAX, last = 0;
  auto count = [&](std::uint16_t channel, std::uint64_t log_time) {
    ++counts_[channel];
    first = std::min(first, log_time);
    last = std::max(last, log_time);
  };
  for (std::uint64_t pos = data_start_; pos < data_end_;) {
    std::uint8_t opcode = 0;
    std::uint64_t length = 0;
    if (!record_is_whole(pos, opcode, length)) break;
    if (opcode == kDataEnd || opcode == kFooter) break;
    const RecordPlace where = place(opcode, pos);
    if (opcode == kSchema || opcode == kChannel || opcode == kMessage) {
      const std::uint64_t wanted = opcode == kMessage ? std::min(length, kMessageFixedBytes) : length;
      if (wanted > kMaxSmallRecord)
        throw Error(fmt::format("{} is {} bytes, more than such a record can sensibly be", where.describe(), length));
      std::vector<std::uint8_t> content(static_cast<std::size_t>(wanted));
      file_.read_at(pos + kRecordPrefix, content.data(), content.size(), where.describe());
      if (opcode == kSchema) add_schema(parse_schema(content, where));
      if (opcode == kChannel) add_channel(parse_channel(content, where), where);
      if (opcode == kMessage) {
        const MessageView m = parse_message(content, where);
        count(m.channel_id, m.log_time);
      }
    } else if (opcode == kChunk) {
      const ChunkHeader header = read_chunk_header(pos, length);
      load_chunk(header, pos, records);
      compressions_.insert(header.compression);
      ++chunk_count_;
      walk_records(records.span(), pos, [&](std::uint8_t op, std::span<const std::uint8_t> content, const RecordPlace& at) {
        if (op == kSchema) add_schema(parse_schema(content, at));
        if (op == kChannel) add_channel(parse_channel(content, at), at);
        if (op == kMessage) {
          const MessageView m = parse_message(content, at);
          count(m.channel_id, m.log_time);
        }
      });
    }
    pos += kRecordPrefix + length;
  }
  if (first != UINT64_MAX)
    range_ = TimeRange{static_cast<std::int64_t>(first), static_cast<std::int64_t>(last)};
}

void McapReader::add_schema(SchemaRecord schema) {
  if (schema.id == 0) return;  // invalid by the specification: ignored
  schemas_.try_emplace(schema.id, std::move(schema));
}

void McapReader::add_channel(const ChannelRecord& channel, const RecordPlace&) {
  // Records with the same id must be identical (specification); the first one is kept.
  channel_records_.try_emplace(channel.id, channel);
}

void McapReader::build_channels() {
  for (const auto& [id, record] : channel_records_) {
    Channel c;
    c.id = id;
    c.topic = record.topic;
    c.encoding = record.message_encoding;
    c.serialization = serialization_of(record.message_encoding);
    if (record.schema_id != 0) {
      const auto schema = schemas_.find(record.schema_id);
      if (schema == schemas_.end()) {
        notes_.push_back(fmt::format("{}: channel {} ({}) refers to schema {}, which the file does not define: its "
                                     "type is unknown",
                                     file_.name(), id, record.topic, record.schema_id));
      } else {
        c.type = ros1_type_name(schema->second.name);
        const std::string& encoding = schema->second.encoding;
        if (encoding == "ros1msg" || encoding == "ros2msg" || encoding == "ros2idl") c.definition = schema->second.data;
      }
    }
    if (const auto count = counts_.find(id); count != counts_.end()) {
      c.message_count = count->second;
    } else if (scanned_) {
      c.message_count = 0;
    }
    channel_index_[id] = static_cast<int>(channels_.size());
    channels_.push_back(std::move(c));
  }
  schemas_.clear();
}

std::string McapReader::describe() const {
  std::string compression;
  for (const auto& name : compressions_) compression += (compression.empty() ? "" : ", ") + (name.empty() ? "none" : name);
  std::string chunks = chunk_count_ == 0 ? std::string("no chunks")
                                         : fmt::format("{} chunk{} ({})", chunk_count_, chunk_count_ == 1 ? "" : "s",
                                                       compression);
  return fmt::format("MCAP, profile \"{}\", {}, {}", profile_, chunks,
                     indexed_ ? "read through its chunk index" : "read linearly");
}

std::vector<std::string> McapReader::notes() const {
  std::vector<std::string> out = notes_;
  if (out_of_order_ > 0)
    out.push_back(fmt::format("{}: {} messages came out earlier in log time than the message before them (the file's "
                              "chunks are out of order beyond what linear reading can reorder)",
                              file_.name(), out_of_order_));
  if (max_open_ > 16)
    out.push_back(fmt::format("{}: up to {} chunks were held in memory at once (their time ranges overlap)",
                              file_.name(), max_open_));
  if (finished_ && !selection_changed_ && statistics_messages_ && delivered_ < *statistics_messages_)
    out.push_back(fmt::format("{}: the summary counts {} messages but {} were found through the chunk index "
                              "(messages outside chunks are not indexed)",
                              file_.name(), *statistics_messages_, delivered_));
  return out;
}

}  // namespace mcap
}  // namespace slamvdb::recording
