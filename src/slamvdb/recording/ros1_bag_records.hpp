#pragma once
// The records of a ROS 1 bag, format 2.0 (http://wiki.ros.org/Bags/Format/2.0): each record is
//   uint32 header_len, header (fields "name=value", each prefixed by its uint32 length),
//   uint32 data_len, data.
// This file parses one record's header and the fields of each record kind; ros1_bag.cpp walks
// the file and the chunks.
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace slamvdb::recording::ros1 {

inline constexpr std::string_view kMagic = "#ROSBAG V2.0\n";
inline constexpr std::uint64_t kBagHeaderOffset = 13;  // after the magic line

// The `op` field of a record header.
enum class Op : std::uint8_t {
  kMessageData = 0x02,
  kBagHeader = 0x03,
  kIndexData = 0x04,
  kChunk = 0x05,
  kChunkInfo = 0x06,
  kConnection = 0x07
};
std::string_view op_name(std::uint8_t op);

// Record headers longer than this are damage, not data (a real one holds a few short fields).
inline constexpr std::uint32_t kMaxRecordHeaderBytes = 1u << 20;

// The fields of one record header (or of a connection record's data, which has the same form);
// the views point into the bytes parsed. Damage throws an Error saying what is wrong, to which the
// reader adds the file and the offset.
class RecordFields {
 public:
  explicit RecordFields(std::span<const std::uint8_t> bytes);
  std::optional<std::span<const std::uint8_t>> find(std::string_view name) const;
  std::uint8_t op() const;  // throws if missing or not 1 byte
  std::uint32_t u32(std::string_view name) const;
  std::uint64_t u64(std::string_view name) const;
  std::int64_t time_ns(std::string_view name) const;  // uint32 sec, uint32 nsec
  std::string_view string(std::string_view name) const;
  std::string_view string_or_empty(std::string_view name) const;

 private:
  std::span<const std::uint8_t> require(std::string_view name, std::size_t size) const;
  struct Field {
    std::string_view name;
    std::span<const std::uint8_t> value;
  };
  std::vector<Field> fields_;
};

struct BagHeader {
  std::uint64_t index_pos = 0;
  std::uint32_t conn_count = 0, chunk_count = 0;
};
BagHeader parse_bag_header(const RecordFields& header);

struct ConnectionRecord {
  std::uint32_t id = 0;
  std::string topic, type, md5sum, message_definition;
};
// `header`: the record header (conn, topic); `data`: its data (type, md5sum, message_definition...).
ConnectionRecord parse_connection(const RecordFields& header, std::span<const std::uint8_t> data);

struct ChunkInfo {
  std::uint64_t chunk_pos = 0;
  std::int64_t start_ns = 0, end_ns = 0;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> counts;  // connection id, messages
};
ChunkInfo parse_chunk_info(const RecordFields& header, std::span<const std::uint8_t> data);

// One record inside a decompressed chunk (connection or message data) or anywhere in a buffer.
struct BufferRecord {
  std::span<const std::uint8_t> header, data;
  std::size_t offset = 0, end = 0;  // of the record in the buffer, and one past its end
};
// The record at `offset` of `buffer`, or nullopt when the buffer ends inside it (`why` says how).
std::optional<BufferRecord> record_at(std::span<const std::uint8_t> buffer, std::size_t offset, std::string& why);

}  // namespace slamvdb::recording::ros1
