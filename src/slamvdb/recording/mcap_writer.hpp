#pragma once
// Writes MCAP files (https://mcap.dev/spec, major version 0) without an MCAP library: Debian 12
// packages none, and the writer is small (the reader beside it, mcap_records.hpp, shares the record
// layout). What it writes is what indexed readers (Foxglove, `mcap` tools, ros2 bag) expect: the
// header, then chunks (zstd through libzstd, or uncompressed) each followed by its message indexes,
// a data end record with the data section's CRC, and a summary section (schemas, channels,
// statistics, chunk indexes) with its summary offsets, a footer with the summary CRC and the
// closing magic. Schema and channel records also go into the chunk where they are first used, so
// that a streaming reader meets them before their messages.
//
// Streaming: memory holds one chunk (records and compressed bytes) and the small summary, never
// the file. The bytes depend only on what is written (no clock, no library version): the same
// messages give the same file. The file goes through OutputFile (all-or-nothing: finish() commits
// it; a writer destroyed before finish() leaves the target as it was).
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace slamvdb::recording::mcap {

struct WriterOptions {
  std::string profile = "ros2";
  std::string library = "slamvdb";
  std::string compression = "zstd";  // "zstd" or "" (uncompressed chunks)
  int zstd_level = 3;
  std::uint64_t chunk_size = std::uint64_t{4} << 20;  // uncompressed records per chunk (a larger message gets its own)
};

struct WriterStats {
  std::uint64_t messages = 0, chunks = 0, bytes = 0;  // bytes: the file's size once finished
  std::uint64_t uncompressed_bytes = 0;               // of the chunks' records
};

class McapWriter {
 public:
  // Throws Error naming `path` if it cannot be written, or for an unknown compression.
  McapWriter(const std::filesystem::path& path, WriterOptions options = {});
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // Ids count from 1 in registration order.
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata = {});
  // One message; `sequence` is the channel's running count. Times in ns since the Unix epoch.
  void write(std::uint16_t channel_id, std::uint64_t log_time, std::uint64_t publish_time,
             std::span<const std::uint8_t> data);
  // The last chunk, the summary and the footer; commits the file.
  WriterStats finish();
  const WriterStats& stats() const { return stats_; }

 private:
  struct State;
  std::unique_ptr<State> state_;
  WriterStats stats_;
};

}  // namespace slamvdb::recording::mcap
