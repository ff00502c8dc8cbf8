#pragma once
// For tests and fuzz seeds only: MCAP files assembled record by record from the specification
// (https://mcap.dev/spec), for shapes no writer makes on request (offsets past 4 GiB, tiny seeds).
// The project has no MCAP writer; the recording tests' other files come from @mcap/core.
#include <cstdint>
#include <string>
#include <vector>

#include "slamvdb/recording/crc32.hpp"

namespace slamvdb::testing::mcap_assembly {

template <typename T>
std::string le(T v) {
  std::string s(sizeof(T), '\0');
  for (std::size_t i = 0; i < sizeof(T); ++i) s[i] = static_cast<char>(static_cast<std::uint64_t>(v) >> (8 * i));
  return s;
}
inline std::string str(const std::string& s) { return le<std::uint32_t>(static_cast<std::uint32_t>(s.size())) + s; }
inline std::string record(std::uint8_t opcode, const std::string& content) {
  return std::string(1, static_cast<char>(opcode)) + le<std::uint64_t>(content.size()) + content;
}
inline const std::string& magic() {
  static const std::string m("\x89MCAP0\r\n", 8);
  return m;
}
inline std::string header(const std::string& profile) { return record(0x01, str(profile) + str("slamvdb tests")); }
inline std::string schema(std::uint16_t id, const std::string& name, const std::string& encoding,
                          const std::string& data) {
  return record(0x03, le(id) + str(name) + str(encoding) + str(data));
}
inline std::string channel(std::uint16_t id, std::uint16_t schema_id, const std::string& topic,
                           const std::string& encoding) {
  return record(0x04, le(id) + le(schema_id) + str(topic) + str(encoding) + le<std::uint32_t>(0));
}
inline std::string message(std::uint16_t channel_id, std::uint64_t log_time, const std::string& data) {
  return record(0x05, le(channel_id) + le<std::uint32_t>(0) + le(log_time) + le(log_time) + data);
}
// A Chunk record holding `records` (compressed as `packed` with `compression`, or as they are).
inline std::string chunk(std::uint64_t start, std::uint64_t end, const std::string& records,
                         const std::string& compression = "", const std::string& packed = "") {
  const std::string& body = compression.empty() ? records : packed;
  return record(0x06, le(start) + le(end) + le<std::uint64_t>(records.size()) +
                          le(recording::crc32(0, records.data(), records.size())) + str(compression) +
                          le<std::uint64_t>(body.size()) + body);
}
inline std::string chunk_index(std::uint64_t start, std::uint64_t end, std::uint64_t offset, std::uint64_t length,
                               const std::vector<std::uint16_t>& channels, const std::string& compression,
                               std::uint64_t compressed, std::uint64_t uncompressed) {
  std::string map;
  for (const std::uint16_t c : channels) map += le(c) + le<std::uint64_t>(0);
  return record(0x08, le(start) + le(end) + le(offset) + le(length) + str(map) + le<std::uint64_t>(0) +
                          str(compression) + le(compressed) + le(uncompressed));
}
inline std::string statistics(std::uint64_t messages, std::uint64_t start, std::uint64_t end,
                              const std::vector<std::pair<std::uint16_t, std::uint64_t>>& counts) {
  std::string map;
  for (const auto& [c, n] : counts) map += le(c) + le(n);
  return record(0x0B, le(messages) + le<std::uint16_t>(1) + le<std::uint32_t>(static_cast<std::uint32_t>(counts.size())) +
                          le<std::uint32_t>(0) + le<std::uint32_t>(0) + le<std::uint32_t>(1) + le(start) + le(end) +
                          str(map));
}
inline std::string data_end() { return record(0x0F, le<std::uint32_t>(0)); }
// The footer and the trailing magic; the summary CRC covers `summary` (the summary section's bytes)
// and the footer up to its CRC field.
inline std::string footer(std::uint64_t summary_start, const std::string& summary) {
  const std::string start = std::string(1, '\x02') + le<std::uint64_t>(20) + le(summary_start) + le<std::uint64_t>(0);
  const std::string covered = summary + start;
  return start + le<std::uint32_t>(summary_start == 0 ? 0 : recording::crc32(0, covered.data(), covered.size())) +
         magic();
}

}  // namespace slamvdb::testing::mcap_assembly
