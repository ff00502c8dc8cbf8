#include "slamvdb/recording/ros1_bag_records.hpp"

#include <fmt/format.h>

#include <cstring>

#include "slamvdb/core/error.hpp"

namespace slamvdb::recording::ros1 {

namespace records_detail {

std::uint32_t load_u32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[3]} << 24;
}

std::string_view as_text(std::span<const std::uint8_t> bytes) {
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

}  // namespace records_detail

using records_detail::load_u32;

std::string_view op_name(std::uint8_t op) {
  switch (static_cast<Op>(op)) {
    case Op::kMessageData: return "message data";
    case Op::kBagHeader: return "bag header";
    case Op::kIndexData: return "index data";
    case Op::kChunk: return "chunk";
    case Op::kChunkInfo: return "chunk info";
    case Op::kConnection: return "connection";
  }
  return "unknown";
}

RecordFields::RecordFields(std::span<const std::uint8_t> bytes) {
  std::size_t pos = 0;
  while (pos < bytes.size()) {
    if (bytes.size() - pos < 4)
      throw Error(fmt::format("the record header ends inside a field length ({} bytes left)", bytes.size() - pos));
    const std::uint32_t length = load_u32(bytes.data() + pos);
    pos += 4;
    if (length > bytes.size() - pos)
      throw Error(fmt::format("a header field of {} bytes runs past the end of the record header ({} bytes left)",
                              length, bytes.size() - pos));
    const auto field = bytes.subspan(pos, length);
    pos += length;
    const auto* equals = static_cast<const std::uint8_t*>(std::memchr(field.data(), '=', field.size()));
    if (!equals) throw Error("a header field has no '=' between its name and value");
    const std::size_t name_length = static_cast<std::size_t>(equals - field.data());
    fields_.push_back({records_detail::as_text(field.first(name_length)), field.subspan(name_length + 1)});
  }
}

std::optional<std::span<const std::uint8_t>> RecordFields::find(std::string_view name) const {
  for (const Field& f : fields_)
    if (f.name == name) return f.value;
  return std::nullopt;
}

std::span<const std::uint8_t> RecordFields::require(std::string_view name, std::size_t size) const {
  const auto value = find(name);
  if (!value) throw Error(fmt::format("the record header has no field '{}'", name));
  if (size > 0 && value->size() != size)
    throw Error(fmt::format("the record header field '{}' has {} bytes, not {}", name, value->size(), size));
  return *value;
}

std::uint8_t RecordFields::op() const { return require("op", 1)[0]; }
std::uint32_t RecordFields::u32(std::string_view name) const { return load_u32(require(name, 4).data()); }

std::uint64_t RecordFields::u64(std::string_view name) const {
  const auto v = require(name, 8);
  return std::uint64_t{load_u32(v.data())} | std::uint64_t{load_u32(v.data() + 4)} << 32;
}

std::int64_t RecordFields::time_ns(std::string_view name) const {
  const auto v = require(name, 8);
  return std::int64_t{load_u32(v.data())} * 1'000'000'000 + load_u32(v.data() + 4);
}

std::string_view RecordFields::string(std::string_view name) const {
  return records_detail::as_text(require(name, 0));
}

std::string_view RecordFields::string_or_empty(std::string_view name) const {
  const auto value = find(name);
  return value ? records_detail::as_text(*value) : std::string_view{};
}

BagHeader parse_bag_header(const RecordFields& header) {
  return {header.u64("index_pos"), header.u32("conn_count"), header.u32("chunk_count")};
}

ConnectionRecord parse_connection(const RecordFields& header, std::span<const std::uint8_t> data) {
  ConnectionRecord c;
  c.id = header.u32("conn");
  c.topic = header.string("topic");
  const RecordFields fields(data);
  c.type = fields.string("type");
  c.md5sum = fields.string_or_empty("md5sum");
  c.message_definition = fields.string_or_empty("message_definition");
  return c;
}

ChunkInfo parse_chunk_info(const RecordFields& header, std::span<const std::uint8_t> data) {
  const std::uint32_t version = header.u32("ver");
  if (version != 1) throw Error(fmt::format("chunk info version {} (only version 1 exists)", version));
  ChunkInfo info;
  info.chunk_pos = header.u64("chunk_pos");
  info.start_ns = header.time_ns("start_time");
  info.end_ns = header.time_ns("end_time");
  const std::uint32_t count = header.u32("count");
  if (count > data.size() / 8 || data.size() != std::size_t{count} * 8)
    throw Error(fmt::format("chunk info lists {} connections in {} bytes (8 bytes each)", count, data.size()));
  info.counts.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i)
    info.counts.emplace_back(load_u32(data.data() + 8 * i), load_u32(data.data() + 8 * i + 4));
  return info;
}

std::optional<BufferRecord> record_at(std::span<const std::uint8_t> buffer, std::size_t offset, std::string& why) {
  const std::size_t left = offset < buffer.size() ? buffer.size() - offset : 0;
  if (left < 4) {
    why = fmt::format("{} bytes, too few for a record", left);
    return std::nullopt;
  }
  const std::uint32_t header_length = load_u32(buffer.data() + offset);
  if (header_length > kMaxRecordHeaderBytes) {
    why = fmt::format("a record header of {} bytes (damaged: real headers are a few dozen bytes)", header_length);
    return std::nullopt;
  }
  if (std::size_t{header_length} + 8 > left) {
    why = fmt::format("a record header of {} bytes with only {} bytes left", header_length, left - 4);
    return std::nullopt;
  }
  const std::uint32_t data_length = load_u32(buffer.data() + offset + 4 + header_length);
  if (data_length > left - 8 - header_length) {
    why = fmt::format("a record with {} data bytes with only {} bytes left", data_length, left - 8 - header_length);
    return std::nullopt;
  }
  BufferRecord r;
  r.offset = offset;
  r.header = buffer.subspan(offset + 4, header_length);
  r.data = buffer.subspan(offset + 8 + header_length, data_length);
  r.end = offset + 8 + header_length + data_length;
  return r;
}

}  // namespace slamvdb::recording::ros1
