#pragma once
// The MCAP records the reader needs, parsed from their bytes (MCAP format specification, major
// version 0: https://mcap.dev/spec). Written by hand: no MCAP library is packaged in Debian 12, and
// the format is small (records of <opcode u8><length u64><fields>, little-endian). Every parse is
// bounds-checked; a record shorter than its fields is an Error naming the file, the record and its
// offset. Fields added by later versions of a record are ignored, as the specification asks.
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace slamvdb::recording::mcap {

inline constexpr std::uint8_t kMagic[8] = {0x89, 'M', 'C', 'A', 'P', 0x30, '\r', '\n'};
inline constexpr std::uint64_t kRecordPrefix = 9;  // opcode + content length
inline constexpr std::uint64_t kFooterContent = 20;
// A footer record and the trailing magic.
inline constexpr std::uint64_t kFooterAndMagic = kRecordPrefix + kFooterContent + sizeof kMagic;

enum Opcode : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

// "Chunk", "Message", ... or "record with opcode 0x42".
std::string opcode_name(std::uint8_t opcode);

// Where a record is, for messages: "<file name>: the <record> record at offset N".
struct RecordPlace {
  std::string_view file;  // PositionalFile::name()
  std::uint8_t opcode = 0;
  std::uint64_t offset = 0;  // of its opcode byte in the file
  // For records inside a chunk: the chunk's offset (the record's offset is then within the chunk's
  // uncompressed records).
  std::uint64_t chunk_offset = UINT64_MAX;
  std::string describe() const;
};

// Little-endian fields of one record's content, bounds-checked.
class FieldReader {
 public:
  FieldReader(std::span<const std::uint8_t> content, const RecordPlace& place) : bytes_(content), place_(place) {}
  std::uint8_t u8();
  std::uint16_t u16();
  std::uint32_t u32();
  std::uint64_t u64();
  std::string_view string();  // uint32 length + bytes
  std::span<const std::uint8_t> bytes32();
  std::span<const std::uint8_t> take(std::uint64_t n);
  // A Map<uint16, uint64>'s keys (e.g. the channels of a chunk index); the values are skipped.
  std::vector<std::uint16_t> u16_keys_of_map();
  void skip_prefixed32();  // a uint32-length-prefixed field not needed (maps of strings, arrays)
  std::uint64_t remaining() const { return bytes_.size() - pos_; }
  std::span<const std::uint8_t> rest() { return take(remaining()); }

 private:
  [[noreturn]] void too_short(std::uint64_t wanted) const;
  std::span<const std::uint8_t> bytes_;
  std::uint64_t pos_ = 0;
  const RecordPlace& place_;
};

struct SchemaRecord {
  std::uint16_t id = 0;
  std::string name, encoding;
  std::string data;
};
SchemaRecord parse_schema(std::span<const std::uint8_t> content, const RecordPlace& place);

struct ChannelRecord {
  std::uint16_t id = 0, schema_id = 0;
  std::string topic, message_encoding;
};
ChannelRecord parse_channel(std::span<const std::uint8_t> content, const RecordPlace& place);

// A Message record's fixed fields (22 bytes) and where its data is.
struct MessageView {
  std::uint16_t channel_id = 0;
  std::uint64_t log_time = 0;
  std::span<const std::uint8_t> data;
};
inline constexpr std::uint64_t kMessageFixedBytes = 2 + 4 + 8 + 8;
MessageView parse_message(std::span<const std::uint8_t> content, const RecordPlace& place);

// A Chunk record without its records: the fixed fields before them. `records_offset` is where the
// (compressed) records start in the file.
struct ChunkHeader {
  std::uint64_t message_start_time = 0, message_end_time = 0, uncompressed_size = 0;
  std::uint32_t uncompressed_crc = 0;
  std::string compression;
  std::uint64_t records_size = 0, records_offset = 0;
};
// `content_start` is the first bytes of the record's content (at least as far as the records
// length); `offset` the record's offset in the file.
ChunkHeader parse_chunk_header(std::span<const std::uint8_t> content_start, std::uint64_t content_length,
                               const RecordPlace& place);

struct ChunkIndexRecord {
  std::uint64_t message_start_time = 0, message_end_time = 0, chunk_start_offset = 0, chunk_length = 0;
  std::vector<std::uint16_t> channels;  // from message_index_offsets; empty: not known
  std::string compression;
  std::uint64_t compressed_size = 0, uncompressed_size = 0;
};
ChunkIndexRecord parse_chunk_index(std::span<const std::uint8_t> content, const RecordPlace& place);

struct StatisticsRecord {
  std::uint64_t message_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t message_start_time = 0, message_end_time = 0;
  std::vector<std::pair<std::uint16_t, std::uint64_t>> channel_message_counts;
};
StatisticsRecord parse_statistics(std::span<const std::uint8_t> content, const RecordPlace& place);

struct FooterRecord {
  std::uint64_t summary_start = 0, summary_offset_start = 0;
  std::uint32_t summary_crc = 0;
};
FooterRecord parse_footer(std::span<const std::uint8_t> content, const RecordPlace& place);

// The Header record's profile ("ros1", "ros2", ...).
std::string parse_header_profile(std::span<const std::uint8_t> content, const RecordPlace& place);

}  // namespace slamvdb::recording::mcap
