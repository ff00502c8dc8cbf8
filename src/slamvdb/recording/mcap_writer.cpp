#include "slamvdb/recording/mcap_writer.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <zstd.h>

#include <algorithm>
#include <limits>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/recording/crc32.hpp"
#include "slamvdb/recording/mcap_records.hpp"

namespace slamvdb::recording::mcap {

// File-local helpers in a named namespace: the unity build merges this file with the reader's.
namespace mcap_writer_cpp {

using Bytes = std::vector<std::uint8_t>;

// Little-endian fields appended to a byte buffer.
void put_u8(Bytes& b, std::uint8_t v) { b.push_back(v); }
void put_u16(Bytes& b, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_u32(Bytes& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_u64(Bytes& b, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put_string(Bytes& b, std::string_view s) {
  put_u32(b, static_cast<std::uint32_t>(s.size()));
  b.insert(b.end(), s.begin(), s.end());
}
void patch_u32(Bytes& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void patch_u64(Bytes& b, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// Starts a record (opcode, length to be patched by end_record); returns where its length is.
std::size_t begin_record(Bytes& b, std::uint8_t opcode) {
  put_u8(b, opcode);
  const std::size_t at = b.size();
  put_u64(b, 0);
  return at;
}
void end_record(Bytes& b, std::size_t length_at) { patch_u64(b, length_at, b.size() - length_at - 8); }

// A length-prefixed (uint32 bytes) group, e.g. a map or an array: begin, append, end.
std::size_t begin_prefixed32(Bytes& b) {
  const std::size_t at = b.size();
  put_u32(b, 0);
  return at;
}
void end_prefixed32(Bytes& b, std::size_t at) { patch_u32(b, at, static_cast<std::uint32_t>(b.size() - at - 4)); }

struct SchemaInfo {
  std::string name, encoding, data;
};
struct ChannelInfo {
  std::uint16_t schema_id = 0;
  std::string topic, message_encoding;
  std::map<std::string, std::string> metadata;
  std::uint32_t sequence = 0;
  std::uint64_t count = 0;
};

void append_schema(Bytes& b, std::uint16_t id, const SchemaInfo& s) {
  const std::size_t r = begin_record(b, kSchema);
  put_u16(b, id);
  put_string(b, s.name);
  put_string(b, s.encoding);
  put_string(b, s.data);
  end_record(b, r);
}
void append_channel(Bytes& b, std::uint16_t id, const ChannelInfo& c) {
  const std::size_t r = begin_record(b, kChannel);
  put_u16(b, id);
  put_u16(b, c.schema_id);
  put_string(b, c.topic);
  put_string(b, c.message_encoding);
  const std::size_t map = begin_prefixed32(b);
  for (const auto& [key, value] : c.metadata) {  // std::map: sorted, so deterministic
    put_string(b, key);
    put_string(b, value);
  }
  end_prefixed32(b, map);
  end_record(b, r);
}

}  // namespace mcap_writer_cpp

struct McapWriter::State {
  WriterOptions options;
  OutputFile out;
  std::uint64_t position = 0;                          // bytes written to the file so far
  std::uint32_t data_crc = 0;                          // of the data section so far (magic included)
  std::vector<mcap_writer_cpp::SchemaInfo> schemas;    // id = index + 1
  std::vector<mcap_writer_cpp::ChannelInfo> channels;  // id = index + 1
  std::vector<bool> schema_in_file, channel_in_file;
  // The chunk being filled: its records, its time range, each channel's (log time, offset) pairs.
  mcap_writer_cpp::Bytes chunk;
  std::uint64_t chunk_start = 0, chunk_end = 0;
  std::map<std::uint16_t, std::vector<std::pair<std::uint64_t, std::uint64_t>>> chunk_index_entries;
  mcap_writer_cpp::Bytes compressed, scratch;
  mcap_writer_cpp::Bytes chunk_indexes;  // the summary's chunk index records
  std::uint64_t message_start = 0, message_end = 0;
  bool finished = false;
  std::unique_ptr<ZSTD_CCtx, decltype(&ZSTD_freeCCtx)> zstd{nullptr, &ZSTD_freeCCtx};

  State(const std::filesystem::path& path, WriterOptions o) : options(std::move(o)), out(path, OutputOptions{}) {}

  void emit(const mcap_writer_cpp::Bytes& bytes, bool data_section) {
    out.write(bytes.data(), bytes.size());
    if (data_section) data_crc = crc32(data_crc, bytes.data(), bytes.size());
    position += bytes.size();
  }

  void flush_chunk(WriterStats& stats);
};

McapWriter::McapWriter(const std::filesystem::path& path, WriterOptions options) {
  if (options.compression != "zstd" && !options.compression.empty())
    throw Error(fmt::format("MCAP writer: unknown chunk compression '{}' (zstd or none)", options.compression));
  state_ = std::make_unique<State>(path, std::move(options));
  if (state_->options.compression == "zstd") {
    state_->zstd.reset(ZSTD_createCCtx());
    if (!state_->zstd) throw Error("MCAP writer: cannot create a zstd context");
  }
  mcap_writer_cpp::Bytes b(std::begin(kMagic), std::end(kMagic));
  const std::size_t r = mcap_writer_cpp::begin_record(b, kHeader);
  mcap_writer_cpp::put_string(b, state_->options.profile);
  mcap_writer_cpp::put_string(b, state_->options.library);
  mcap_writer_cpp::end_record(b, r);
  state_->emit(b, true);
}

McapWriter::~McapWriter() = default;  // without finish(): OutputFile leaves the target untouched

std::uint16_t McapWriter::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  if (state_->schemas.size() >= std::numeric_limits<std::uint16_t>::max()) throw Error("MCAP writer: too many schemas");
  state_->schemas.push_back({name, encoding, data});
  state_->schema_in_file.push_back(false);
  return static_cast<std::uint16_t>(state_->schemas.size());
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, const std::string& topic,
                                      const std::string& message_encoding,
                                      const std::map<std::string, std::string>& metadata) {
  if (schema_id == 0 || schema_id > state_->schemas.size())
    throw Error(fmt::format("MCAP writer: channel {} names schema {}, which was not added", topic, schema_id));
  if (state_->channels.size() >= std::numeric_limits<std::uint16_t>::max())
    throw Error("MCAP writer: too many channels");
  state_->channels.push_back({schema_id, topic, message_encoding, metadata});
  state_->channel_in_file.push_back(false);
  return static_cast<std::uint16_t>(state_->channels.size());
}

void McapWriter::write(std::uint16_t channel_id, std::uint64_t log_time, std::uint64_t publish_time,
                       std::span<const std::uint8_t> data) {
  State& s = *state_;
  if (s.finished) throw Error("MCAP writer: write after finish");
  if (channel_id == 0 || channel_id > s.channels.size())
    throw Error(fmt::format("MCAP writer: message on channel {}, which was not added", channel_id));
  mcap_writer_cpp::ChannelInfo& channel = s.channels[channel_id - 1];
  // A message does not split: a chunk that would grow past chunk_size is written first.
  if (!s.chunk.empty() && s.chunk.size() + data.size() + 31 > s.options.chunk_size) s.flush_chunk(stats_);
  if (!s.schema_in_file[channel.schema_id - 1]) {
    mcap_writer_cpp::append_schema(s.chunk, channel.schema_id, s.schemas[channel.schema_id - 1]);
    s.schema_in_file[channel.schema_id - 1] = true;
  }
  if (!s.channel_in_file[channel_id - 1]) {
    mcap_writer_cpp::append_channel(s.chunk, channel_id, channel);
    s.channel_in_file[channel_id - 1] = true;
  }
  if (s.chunk_index_entries.empty()) s.chunk_start = s.chunk_end = log_time;
  s.chunk_start = std::min(s.chunk_start, log_time);
  s.chunk_end = std::max(s.chunk_end, log_time);
  s.chunk_index_entries[channel_id].emplace_back(log_time, s.chunk.size());
  const std::size_t r = mcap_writer_cpp::begin_record(s.chunk, kMessage);
  mcap_writer_cpp::put_u16(s.chunk, channel_id);
  mcap_writer_cpp::put_u32(s.chunk, channel.sequence++);
  mcap_writer_cpp::put_u64(s.chunk, log_time);
  mcap_writer_cpp::put_u64(s.chunk, publish_time);
  s.chunk.insert(s.chunk.end(), data.begin(), data.end());
  mcap_writer_cpp::end_record(s.chunk, r);
  if (stats_.messages == 0) s.message_start = s.message_end = log_time;
  s.message_start = std::min(s.message_start, log_time);
  s.message_end = std::max(s.message_end, log_time);
  ++channel.count;
  ++stats_.messages;
}

void McapWriter::State::flush_chunk(WriterStats& stats) {
  if (chunk.empty()) return;
  const std::uint32_t records_crc = crc32(0, chunk.data(), chunk.size());
  std::span<const std::uint8_t> records(chunk);
  if (zstd) {
    compressed.resize(ZSTD_compressBound(chunk.size()));
    const std::size_t n = ZSTD_compressCCtx(zstd.get(), compressed.data(), compressed.size(), chunk.data(),
                                            chunk.size(), options.zstd_level);
    if (ZSTD_isError(n)) throw Error(fmt::format("MCAP writer: zstd: {}", ZSTD_getErrorName(n)));
    records = std::span<const std::uint8_t>(compressed.data(), n);
  }
  // The chunk record (its records streamed after its fixed fields) ...
  const std::uint64_t chunk_offset = position;
  scratch.clear();
  mcap_writer_cpp::put_u8(scratch, kChunk);
  const std::string_view compression = zstd ? "zstd" : "";
  mcap_writer_cpp::put_u64(scratch, 8 + 8 + 8 + 4 + 4 + compression.size() + 8 + records.size());
  mcap_writer_cpp::put_u64(scratch, chunk_start);
  mcap_writer_cpp::put_u64(scratch, chunk_end);
  mcap_writer_cpp::put_u64(scratch, chunk.size());
  mcap_writer_cpp::put_u32(scratch, records_crc);
  mcap_writer_cpp::put_string(scratch, compression);
  mcap_writer_cpp::put_u64(scratch, records.size());
  emit(scratch, true);
  out.write(records.data(), records.size());
  data_crc = crc32(data_crc, records.data(), records.size());
  position += records.size();
  const std::uint64_t chunk_length = position - chunk_offset;
  // ... then one message index per channel in it, in channel order.
  std::map<std::uint16_t, std::uint64_t> index_offsets;
  scratch.clear();
  for (const auto& [channel_id, entries] : chunk_index_entries) {
    index_offsets[channel_id] = position + scratch.size();
    const std::size_t r = mcap_writer_cpp::begin_record(scratch, kMessageIndex);
    mcap_writer_cpp::put_u16(scratch, channel_id);
    mcap_writer_cpp::put_u32(scratch, static_cast<std::uint32_t>(entries.size() * 16));
    for (const auto& [time, offset] : entries) {
      mcap_writer_cpp::put_u64(scratch, time);
      mcap_writer_cpp::put_u64(scratch, offset);
    }
    mcap_writer_cpp::end_record(scratch, r);
  }
  const std::uint64_t index_length = scratch.size();
  emit(scratch, true);
  // The summary's chunk index.
  const std::size_t r = mcap_writer_cpp::begin_record(chunk_indexes, kChunkIndex);
  mcap_writer_cpp::put_u64(chunk_indexes, chunk_start);
  mcap_writer_cpp::put_u64(chunk_indexes, chunk_end);
  mcap_writer_cpp::put_u64(chunk_indexes, chunk_offset);
  mcap_writer_cpp::put_u64(chunk_indexes, chunk_length);
  const std::size_t map = mcap_writer_cpp::begin_prefixed32(chunk_indexes);
  for (const auto& [channel_id, offset] : index_offsets) {
    mcap_writer_cpp::put_u16(chunk_indexes, channel_id);
    mcap_writer_cpp::put_u64(chunk_indexes, offset);
  }
  mcap_writer_cpp::end_prefixed32(chunk_indexes, map);
  mcap_writer_cpp::put_u64(chunk_indexes, index_length);
  mcap_writer_cpp::put_string(chunk_indexes, compression);
  mcap_writer_cpp::put_u64(chunk_indexes, records.size());
  mcap_writer_cpp::put_u64(chunk_indexes, chunk.size());
  mcap_writer_cpp::end_record(chunk_indexes, r);
  stats.uncompressed_bytes += chunk.size();
  ++stats.chunks;
  chunk.clear();
  chunk_index_entries.clear();
}

WriterStats McapWriter::finish() {
  State& s = *state_;
  if (s.finished) return stats_;
  s.flush_chunk(stats_);
  mcap_writer_cpp::Bytes b;
  std::size_t r = mcap_writer_cpp::begin_record(b, kDataEnd);
  mcap_writer_cpp::put_u32(b, s.data_crc);  // the data section's bytes before this record
  mcap_writer_cpp::end_record(b, r);
  s.emit(b, false);

  // The summary: schemas, channels, statistics, chunk indexes; each group's place for the offsets.
  const std::uint64_t summary_start = s.position;
  mcap_writer_cpp::Bytes summary;
  struct Group {
    std::uint8_t opcode;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  const auto group = [&](std::uint8_t opcode, std::size_t from) {
    if (summary.size() > from) groups.push_back({opcode, summary_start + from, summary.size() - from});
  };
  std::size_t from = summary.size();
  for (std::size_t i = 0; i < s.schemas.size(); ++i)
    mcap_writer_cpp::append_schema(summary, static_cast<std::uint16_t>(i + 1), s.schemas[i]);
  group(kSchema, from);
  from = summary.size();
  for (std::size_t i = 0; i < s.channels.size(); ++i)
    mcap_writer_cpp::append_channel(summary, static_cast<std::uint16_t>(i + 1), s.channels[i]);
  group(kChannel, from);
  from = summary.size();
  r = mcap_writer_cpp::begin_record(summary, kStatistics);
  mcap_writer_cpp::put_u64(summary, stats_.messages);
  mcap_writer_cpp::put_u16(summary, static_cast<std::uint16_t>(s.schemas.size()));
  mcap_writer_cpp::put_u32(summary, static_cast<std::uint32_t>(s.channels.size()));
  mcap_writer_cpp::put_u32(summary, 0);  // attachments
  mcap_writer_cpp::put_u32(summary, 0);  // metadata
  mcap_writer_cpp::put_u32(summary, static_cast<std::uint32_t>(stats_.chunks));
  mcap_writer_cpp::put_u64(summary, s.message_start);
  mcap_writer_cpp::put_u64(summary, s.message_end);
  const std::size_t counts = mcap_writer_cpp::begin_prefixed32(summary);
  for (std::size_t i = 0; i < s.channels.size(); ++i) {
    mcap_writer_cpp::put_u16(summary, static_cast<std::uint16_t>(i + 1));
    mcap_writer_cpp::put_u64(summary, s.channels[i].count);
  }
  mcap_writer_cpp::end_prefixed32(summary, counts);
  mcap_writer_cpp::end_record(summary, r);
  group(kStatistics, from);
  from = summary.size();
  summary.insert(summary.end(), s.chunk_indexes.begin(), s.chunk_indexes.end());
  group(kChunkIndex, from);

  const std::uint64_t summary_offset_start = summary_start + summary.size();
  for (const Group& g : groups) {
    r = mcap_writer_cpp::begin_record(summary, kSummaryOffset);
    mcap_writer_cpp::put_u8(summary, g.opcode);
    mcap_writer_cpp::put_u64(summary, g.start);
    mcap_writer_cpp::put_u64(summary, g.length);
    mcap_writer_cpp::end_record(summary, r);
  }
  // The footer; its CRC covers the summary and the footer's fields before it.
  mcap_writer_cpp::put_u8(summary, kFooter);
  mcap_writer_cpp::put_u64(summary, kFooterContent);  // known up front: the CRC covers it
  mcap_writer_cpp::put_u64(summary, summary_start);
  mcap_writer_cpp::put_u64(summary, summary_offset_start);
  mcap_writer_cpp::put_u32(summary, crc32(0, summary.data(), summary.size()));
  summary.insert(summary.end(), std::begin(kMagic), std::end(kMagic));
  s.emit(summary, false);
  s.out.commit();
  s.finished = true;
  stats_.bytes = s.position;
  return stats_;
}

}  // namespace slamvdb::recording::mcap
