#include "slamvdb/recording/ros1_bag.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <algorithm>
#include <cstring>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/ros1_bag_reader.hpp"

namespace slamvdb::recording {

namespace ros1 {

Ros1BagReader::Ros1BagReader(const std::filesystem::path& path, const Ros1BagOptions& options)
    : path_(path), options_(options), file_(path, "ROS 1 bag") {
  char magic[kMagic.size()] = {};
  if (file_.size() < kMagic.size())
    throw Error(fmt::format("ROS 1 bag {} has {} bytes: too short for a bag", path_, file_.size()));
  file_.read_at(0, magic, sizeof(magic), "the bag's magic line");
  const std::string_view found(magic, sizeof(magic));
  if (found != kMagic) {
    if (found.starts_with("#ROSRECORD V1") || found.starts_with("#ROSBAG V1"))
      throw Error(fmt::format("ROS 1 bag {} has format 1.x (before 2010), which is not read: only format 2.0", path_));
    throw Error(fmt::format("ROS 1 bag {} does not start with \"#ROSBAG V2.0\": it is not a ROS 1 bag", path_));
  }
  std::string why;
  const auto record = read_record(kBagHeaderOffset, why);
  if (!record) fail(kBagHeaderOffset, "the bag header record is damaged: " + why);
  const RecordFields fields = fields_of(*record);
  BagHeader header;
  try {
    if (fields.op() != static_cast<std::uint8_t>(Op::kBagHeader))
      throw Error(fmt::format("the first record is a {} record, not the bag header", op_name(fields.op())));
    header = parse_bag_header(fields);
  } catch (const Error& e) {
    fail(kBagHeaderOffset, e.what());
  }
  linear_offset_ = record->end();
  if (header.index_pos == 0)
    note("no index (the bag header's index_pos is 0: the recording was not closed, e.g. the recorder was killed): "
         "read linearly, in the order written, each chunk's messages in time order");
  else if (header.index_pos < linear_offset_ || header.index_pos >= file_.size())
    note(fmt::format("no index: its position {} is outside the file of {} bytes (cut short?): read linearly, in the "
                     "order written, each chunk's messages in time order",
                     header.index_pos, file_.size()));
  else
    indexed_ = read_index(header);
  if (!indexed_) {
    channels_.clear();
    channel_of_connection_.clear();
    // Channels are found while reading: room reserved so that they do not move (Message::channel).
    channels_.reserve(4096);
    channels_reserved_ = true;
    note_compression_at(linear_offset_);
  }
}

void Ros1BagReader::note_compression_at(std::uint64_t offset) {
  // The compression is in each chunk's own header: the first one says what the bag uses (for
  // describe() before reading; the others are added as they are read).
  std::string why;
  try {
    if (const auto record = read_record(offset, why))
      if (const auto compression = RecordFields(record->header).find("compression"))
        compressions_.insert(std::string(reinterpret_cast<const char*>(compression->data()), compression->size()));
  } catch (const Error&) {
    // Damage there is reported when the chunk is read.
  }
}

void Ros1BagReader::fail(std::uint64_t offset, std::string_view what) const {
  throw Error(fmt::format("ROS 1 bag {}: at offset {}: {}", path_, offset, what));
}

void Ros1BagReader::note(std::string text) { notes_.push_back(std::move(text)); }

std::vector<std::string> Ros1BagReader::notes() const { return notes_; }

std::string Ros1BagReader::describe() const {
  std::string compression;
  for (const std::string& c : compressions_)
    compression += (compression.empty() ? "" : " and ") + (c == "none" ? std::string("uncompressed") : c);
  return fmt::format("ROS 1 bag (format 2.0, {} chunks, {})", compression.empty() ? "no" : compression,
                     indexed_ ? "indexed" : "no index: read linearly");
}

void Ros1BagReader::add_channel(const ConnectionRecord& connection) {
  const auto known = channel_of_connection_.find(connection.id);
  if (known != channel_of_connection_.end()) {
    const Channel& c = channels_[known->second];
    if (c.topic != connection.topic || c.type != connection.type)
      throw Error(fmt::format("connection {} is {} ({}) here but {} ({}) in an earlier record", connection.id,
                               connection.topic, connection.type, c.topic, c.type));
    return;
  }
  if (channels_reserved_ && channels_.size() == channels_.capacity())
    throw Error(fmt::format("more than {} connections in a bag without index", channels_.capacity()));
  Channel channel;
  channel.id = connection.id;
  channel.topic = connection.topic;
  channel.type = connection.type;
  channel.serialization = Serialization::kRos1;
  channel.encoding = "ros1";
  channel.definition = connection.message_definition;
  channel_of_connection_[connection.id] = channels_.size();
  channels_.push_back(std::move(channel));
}

bool Ros1BagReader::read_index(const BagHeader& header) {
  std::vector<ChunkInfo> infos;
  try {
    std::uint64_t offset = header.index_pos;
    std::vector<std::uint8_t> data;
    while (offset < file_.size()) {
      std::string why;
      const auto record = read_record(offset, why);
      if (!record) throw Error(fmt::format("at offset {}: {}", offset, why));
      if (record->end() > file_.size())
        throw Error(fmt::format("at offset {}: a record of {} data bytes runs past the end of the file", offset,
                                record->data_length));
      data.resize(record->data_length);
      file_.read_at(record->data_offset, data.data(), data.size(), "an index record's data");
      const RecordFields fields(record->header);
      const std::uint8_t op = fields.op();
      if (op == static_cast<std::uint8_t>(Op::kConnection))
        add_channel(parse_connection(fields, data));
      else if (op == static_cast<std::uint8_t>(Op::kChunkInfo))
        infos.push_back(parse_chunk_info(fields, data));
      else
        throw Error(fmt::format("at offset {}: a {} record (op {:#04x}) among the index records", offset,
                                op_name(op), op));
      offset = record->end();
    }
    std::set<std::uint64_t> seen;
    for (const ChunkInfo& info : infos) {
      if (info.chunk_pos < linear_offset_ || info.chunk_pos >= header.index_pos)
        throw Error(fmt::format("a chunk info points to offset {}, outside the chunks ({} .. {})", info.chunk_pos,
                                linear_offset_, header.index_pos));
      if (!seen.insert(info.chunk_pos).second)
        throw Error(fmt::format("two chunk infos point to the chunk at offset {}", info.chunk_pos));
    }
  } catch (const Error& e) {
    note(fmt::format("the index at offset {} is damaged ({}): read linearly, in the order written",
                     header.index_pos, e.what()));
    return false;
  }
  if (infos.size() != header.chunk_count)
    note(fmt::format("the bag header counts {} chunks, its index lists {}", header.chunk_count, infos.size()));
  std::map<std::uint32_t, std::uint64_t> counts;
  for (const ChunkInfo& info : infos)
    for (const auto& [connection, count] : info.counts) counts[connection] += count;
  for (Channel& channel : channels_) channel.message_count = counts[channel.id];
  for (const auto& [connection, count] : counts)
    if (!channel_of_connection_.count(connection) && count > 0)
      note(fmt::format("the index counts {} messages on connection {}, which has no connection record", count,
                       connection));
  if (!infos.empty()) {
    TimeRange range{INT64_MAX, INT64_MIN};
    for (const ChunkInfo& info : infos) {
      range.start_ns = std::min(range.start_ns, info.start_ns);
      range.end_ns = std::max(range.end_ns, info.end_ns);
    }
    time_range_ = range;
  }
  std::sort(infos.begin(), infos.end(), [](const ChunkInfo& a, const ChunkInfo& b) {
    return a.start_ns != b.start_ns ? a.start_ns < b.start_ns : a.chunk_pos < b.chunk_pos;
  });
  chunks_ = std::move(infos);
  if (!chunks_.empty()) note_compression_at(chunks_.front().chunk_pos);
  return true;
}

void Ros1BagReader::open_chunk(const ChunkInfo& info) {
  std::string why;
  const auto record = read_record(info.chunk_pos, why);
  if (!record) fail(info.chunk_pos, "the chunk the index points to is damaged: " + why);
  const auto chunk = open_.emplace(open_.end());
  chunk->self = chunk;
  chunk->file_offset = info.chunk_pos;
  try {
    load_chunk(*record, *chunk, false);
    scan_chunk(*chunk, false);
  } catch (...) {
    open_.erase(chunk);
    throw;
  }
  if (chunk->entries.empty()) {
    open_.erase(chunk);
    return;
  }
  chunk->resident = true;
  chunk->data_size = chunk->data.size();
  resident_bytes_ += chunk->data_size;
  pending_.push({chunk->entries.front().time_ns, chunk->file_offset, 0, &*chunk});
  evict_beyond_budget(*chunk);
}

void Ros1BagReader::evict_beyond_budget(const OpenChunk& keep) {
  while (resident_bytes_ > options_.chunk_memory_bytes) {
    // The chunk whose next message comes last is needed last.
    OpenChunk* victim = nullptr;
    for (OpenChunk& c : open_)
      if (&c != &keep && c.resident && c.next < c.entries.size() &&
          (!victim || c.entries[c.next].time_ns > victim->entries[victim->next].time_ns))
        victim = &c;
    if (!victim) return;
    victim->data = {};
    victim->resident = false;
    resident_bytes_ -= victim->data_size;
  }
}

void Ros1BagReader::make_resident(OpenChunk& chunk) {
  std::string why;
  const auto record = read_record(chunk.file_offset, why);
  if (!record) fail(chunk.file_offset, "the chunk is damaged: " + why);
  load_chunk(*record, chunk, false);
  if (chunk.data.size() != chunk.data_size)
    fail(chunk.file_offset, "the chunk changed while the bag was being read");
  chunk.resident = true;
  resident_bytes_ += chunk.data_size;
  evict_beyond_budget(chunk);
}

void Ros1BagReader::emit(const OpenChunk& chunk, const ChunkEntry& entry, Message& out) {
  out.channel = &channels_[channel_of_connection_.at(entry.connection)];
  out.log_time_ns = entry.time_ns;
  out.data = std::span<const std::uint8_t>(chunk.data).subspan(entry.offset, entry.length);
  out.index = message_index_++;
  if (entry.time_ns < last_time_ns_ && indexed_ && !out_of_order_noted_) {
    out_of_order_noted_ = true;
    note(fmt::format("message {} is earlier than the one before it: the index's chunk times disagree with the chunks "
                     "(read in the order found)",
                     out.index));
  }
  last_time_ns_ = std::max(last_time_ns_, entry.time_ns);
}

bool Ros1BagReader::next_indexed(Message& out) {
  const auto release = [this](std::list<OpenChunk>::iterator chunk) {
    if (chunk->resident) resident_bytes_ -= chunk->data_size;
    open_.erase(chunk);
  };
  if (finished_) {
    release(*finished_);
    finished_.reset();
  }
  while (true) {
    // Open every chunk that starts before the earliest message pending: it may hold earlier ones.
    while (next_chunk_ < chunks_.size() &&
           (pending_.empty() || chunks_[next_chunk_].start_ns <= pending_.top().time_ns)) {
      const ChunkInfo& info = chunks_[next_chunk_++];
      const bool any = std::any_of(info.counts.begin(), info.counts.end(),
                                   [&](const auto& count) { return count.second > 0 && wanted(count.first); });
      if (any) open_chunk(info);
    }
    if (pending_.empty()) return false;
    OpenChunk& chunk = *pending_.top().chunk;
    pending_.pop();
    const ChunkEntry& entry = chunk.entries[chunk.next++];
    const bool exhausted = chunk.next == chunk.entries.size();
    if (!exhausted) pending_.push({chunk.entries[chunk.next].time_ns, chunk.file_offset, chunk.next, &chunk});
    if (!wanted(entry.connection)) {
      if (exhausted) release(chunk.self);
      continue;
    }
    if (!chunk.resident) make_resident(chunk);
    emit(chunk, entry, out);
    if (exhausted) finished_ = chunk.self;
    return true;
  }
}

bool Ros1BagReader::next(Message& out) { return indexed_ ? next_indexed(out) : next_linear(out); }

}  // namespace ros1

std::unique_ptr<RecordingReader> open_ros1_bag(const std::filesystem::path& path) {
  return std::make_unique<ros1::Ros1BagReader>(path, Ros1BagOptions{});
}

std::unique_ptr<RecordingReader> open_ros1_bag(const std::filesystem::path& path, const Ros1BagOptions& options) {
  return std::make_unique<ros1::Ros1BagReader>(path, options);
}

}  // namespace slamvdb::recording
