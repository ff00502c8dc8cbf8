#include "slamvdb/recording/mcap_records.hpp"

#include <fmt/format.h>

#include <cstring>

#include "slamvdb/core/error.hpp"

namespace slamvdb::recording::mcap {

std::string opcode_name(std::uint8_t opcode) {
  switch (opcode) {
    case kHeader: return "Header";
    case kFooter: return "Footer";
    case kSchema: return "Schema";
    case kChannel: return "Channel";
    case kMessage: return "Message";
    case kChunk: return "Chunk";
    case kMessageIndex: return "Message Index";
    case kChunkIndex: return "Chunk Index";
    case kAttachment: return "Attachment";
    case kAttachmentIndex: return "Attachment Index";
    case kStatistics: return "Statistics";
    case kMetadata: return "Metadata";
    case kMetadataIndex: return "Metadata Index";
    case kSummaryOffset: return "Summary Offset";
    case kDataEnd: return "Data End";
  }
  return fmt::format("record with opcode 0x{:02x}", opcode);
}

std::string RecordPlace::describe() const {
  if (chunk_offset != UINT64_MAX)
    return fmt::format("{}: the {} record at byte {} of the Chunk at offset {}", file, opcode_name(opcode), offset,
                       chunk_offset);
  return fmt::format("{}: the {} record at offset {}", file, opcode_name(opcode), offset);
}

void FieldReader::too_short(std::uint64_t wanted) const {
  throw Error(fmt::format("{} is shorter than its fields say (needs {} more bytes at byte {} of its {})",
                          place_.describe(), wanted - remaining(), pos_, bytes_.size()));
}

std::span<const std::uint8_t> FieldReader::take(std::uint64_t n) {
  if (n > remaining()) too_short(n);
  const auto out = bytes_.subspan(static_cast<std::size_t>(pos_), static_cast<std::size_t>(n));
  pos_ += n;
  return out;
}

namespace mcap_records_cpp {
template <typename T>
T little_endian(std::span<const std::uint8_t> b) {
  T v = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) v |= static_cast<T>(b[i]) << (8 * i);
  return v;
}
}  // namespace mcap_records_cpp
using namespace mcap_records_cpp;

std::uint8_t FieldReader::u8() { return take(1)[0]; }
std::uint16_t FieldReader::u16() { return little_endian<std::uint16_t>(take(2)); }
std::uint32_t FieldReader::u32() { return little_endian<std::uint32_t>(take(4)); }
std::uint64_t FieldReader::u64() { return little_endian<std::uint64_t>(take(8)); }

std::string_view FieldReader::string() {
  const auto b = bytes32();
  return {reinterpret_cast<const char*>(b.data()), b.size()};
}

std::span<const std::uint8_t> FieldReader::bytes32() {
  const std::uint32_t n = u32();
  return take(n);
}

void FieldReader::skip_prefixed32() { bytes32(); }

std::vector<std::uint16_t> FieldReader::u16_keys_of_map() {
  FieldReader map(bytes32(), place_);
  std::vector<std::uint16_t> keys;
  keys.reserve(static_cast<std::size_t>(map.remaining() / 10));
  while (map.remaining() > 0) {
    keys.push_back(map.u16());
    map.u64();
  }
  return keys;
}

SchemaRecord parse_schema(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  SchemaRecord s;
  s.id = r.u16();
  s.name = r.string();
  s.encoding = r.string();
  const auto data = r.bytes32();
  s.data.assign(reinterpret_cast<const char*>(data.data()), data.size());
  return s;
}

ChannelRecord parse_channel(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  ChannelRecord c;
  c.id = r.u16();
  c.schema_id = r.u16();
  c.topic = r.string();
  c.message_encoding = r.string();
  r.skip_prefixed32();  // metadata
  return c;
}

MessageView parse_message(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  MessageView m;
  m.channel_id = r.u16();
  r.u32();  // sequence
  m.log_time = r.u64();
  r.u64();  // publish time
  m.data = r.rest();
  return m;
}

ChunkHeader parse_chunk_header(std::span<const std::uint8_t> content_start, std::uint64_t content_length,
                               const RecordPlace& place) {
  FieldReader r(content_start, place);
  ChunkHeader h;
  h.message_start_time = r.u64();
  h.message_end_time = r.u64();
  h.uncompressed_size = r.u64();
  h.uncompressed_crc = r.u32();
  h.compression = r.string();
  h.records_size = r.u64();
  const std::uint64_t fixed = content_start.size() - r.remaining();
  if (h.records_size > content_length - fixed)
    throw Error(fmt::format("{} says its records are {} bytes, more than the {} bytes left in the record",
                            place.describe(), h.records_size, content_length - fixed));
  h.records_offset = place.offset + kRecordPrefix + fixed;
  return h;
}

ChunkIndexRecord parse_chunk_index(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  ChunkIndexRecord c;
  c.message_start_time = r.u64();
  c.message_end_time = r.u64();
  c.chunk_start_offset = r.u64();
  c.chunk_length = r.u64();
  c.channels = r.u16_keys_of_map();
  r.u64();  // message_index_length
  c.compression = r.string();
  c.compressed_size = r.u64();
  c.uncompressed_size = r.u64();
  return c;
}

StatisticsRecord parse_statistics(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  StatisticsRecord s;
  s.message_count = r.u64();
  r.u16();  // schema_count
  r.u32();  // channel_count
  r.u32();  // attachment_count
  r.u32();  // metadata_count
  s.chunk_count = r.u32();
  s.message_start_time = r.u64();
  s.message_end_time = r.u64();
  FieldReader counts(r.bytes32(), place);
  while (counts.remaining() > 0) {
    const std::uint16_t channel = counts.u16();
    s.channel_message_counts.emplace_back(channel, counts.u64());
  }
  return s;
}

FooterRecord parse_footer(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  FooterRecord f;
  f.summary_start = r.u64();
  f.summary_offset_start = r.u64();
  f.summary_crc = r.u32();
  return f;
}

std::string parse_header_profile(std::span<const std::uint8_t> content, const RecordPlace& place) {
  FieldReader r(content, place);
  return std::string(r.string());
}

}  // namespace slamvdb::recording::mcap
