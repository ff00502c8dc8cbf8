#pragma once
// Internal to the ROS 1 bag reader (ros1_bag.cpp: opening, the index and the time-ordered merge;
// ros1_bag_chunks.cpp: reading records and chunks, and the linear reading of an unindexed bag).
#include <list>
#include <map>
#include <optional>
#include <queue>
#include <set>
#include <string>
#include <vector>

#include "slamvdb/recording/decompress.hpp"
#include "slamvdb/recording/positional_file.hpp"
#include "slamvdb/recording/ros1_bag.hpp"
#include "slamvdb/recording/ros1_bag_records.hpp"

namespace slamvdb::recording::ros1 {

// A record of the file: its header read, its data not yet.
struct FileRecord {
  std::uint64_t offset = 0;
  std::vector<std::uint8_t> header;
  std::uint64_t data_offset = 0;
  std::uint32_t data_length = 0;
  std::uint64_t end() const { return data_offset + data_length; }
};

// One message found in a decompressed chunk.
struct ChunkEntry {
  std::int64_t time_ns = 0;
  std::uint32_t connection = 0;
  std::uint32_t length = 0;
  std::uint64_t offset = 0;  // of the message bytes in the decompressed chunk
};

struct OpenChunk {
  std::uint64_t file_offset = 0;  // of the chunk record: the order of equal times
  std::vector<ChunkEntry> entries;  // in time order (stable: equal times as written)
  std::size_t next = 0;
  std::vector<std::uint8_t> data;  // decompressed; empty while evicted
  std::uint64_t data_size = 0;     // when resident
  bool resident = false;
  std::list<OpenChunk>::iterator self;
};

class Ros1BagReader final : public RecordingReader {
 public:
  Ros1BagReader(const std::filesystem::path& path, const Ros1BagOptions& options);

  std::string describe() const override;
  const std::vector<Channel>& channels() const override { return channels_; }
  std::optional<TimeRange> time_range() const override { return time_range_; }
  std::uint64_t size_bytes() const override { return file_.size(); }
  void select(const std::set<std::uint32_t>& channel_ids) override { selected_ = channel_ids; }
  bool next(Message& out) override;
  std::uint64_t bytes_read() const override { return file_.bytes_read(); }
  std::vector<std::string> notes() const override;

 private:
  // ros1_bag.cpp
  bool read_index(const BagHeader& header);
  void open_chunk(const ChunkInfo& info);
  void make_resident(OpenChunk& chunk);
  bool next_indexed(Message& out);
  bool wanted(std::uint32_t connection) const { return selected_.empty() || selected_.count(connection) > 0; }
  void add_channel(const ConnectionRecord& connection);
  void note(std::string text);
  void note_compression_at(std::uint64_t offset);
  [[noreturn]] void fail(std::uint64_t offset, std::string_view what) const;

  // ros1_bag_chunks.cpp
  std::optional<FileRecord> read_record(std::uint64_t offset, std::string& why);
  RecordFields fields_of(const FileRecord& record) const;
  // Decompresses the chunk record into chunk.data. `salvage`: a chunk cut by the end of the
  // file, or unfinished; what decompresses is kept and the loss returned (empty: none).
  // `unfinished`: the record is the place-holder header of a chunk the recorder never finished
  // (sizes 0): its data are whatever follows, up to the end of the file.
  std::string load_chunk(const FileRecord& record, OpenChunk& chunk, bool salvage, bool unfinished = false);
  // Lists the messages of chunk.data (connections found on the way are added); returns what stopped
  // the scan early when `salvage` (else an Error).
  std::string scan_chunk(OpenChunk& chunk, bool salvage);
  bool next_linear(Message& out);
  void advance_linear();
  void emit(const OpenChunk& chunk, const ChunkEntry& entry, Message& out);
  void evict_beyond_budget(const OpenChunk& keep);

  std::filesystem::path path_;
  Ros1BagOptions options_;
  PositionalFile file_;
  std::vector<Channel> channels_;
  bool channels_reserved_ = false;  // no index: channels found while reading, in reserved room
  std::map<std::uint32_t, std::size_t> channel_of_connection_;
  std::optional<TimeRange> time_range_;
  std::set<std::uint32_t> selected_;
  std::set<std::string> compressions_;
  std::vector<std::string> notes_;
  std::uint64_t message_index_ = 0;
  std::int64_t last_time_ns_ = INT64_MIN;
  bool out_of_order_noted_ = false;
  std::vector<std::uint8_t> compressed_;  // reused for each chunk's compressed bytes
  Decompressor decompressor_;

  bool indexed_ = false;
  // Indexed: the chunks by (start time, file offset), the next to open, the open ones and the
  // merge of their next messages.
  std::vector<ChunkInfo> chunks_;
  std::size_t next_chunk_ = 0;
  std::list<OpenChunk> open_;
  std::uint64_t resident_bytes_ = 0;
  std::optional<std::list<OpenChunk>::iterator> finished_;  // released at the next call
  struct Pending {
    std::int64_t time_ns;
    std::uint64_t file_offset;
    std::size_t index;
    OpenChunk* chunk;
    bool operator>(const Pending& o) const {
      if (time_ns != o.time_ns) return time_ns > o.time_ns;
      if (file_offset != o.file_offset) return file_offset > o.file_offset;
      return index > o.index;
    }
  };
  std::priority_queue<Pending, std::vector<Pending>, std::greater<>> pending_;

  // Linear (no index): the next record's offset and the chunk being read.
  std::uint64_t linear_offset_ = 0;
  bool linear_done_ = false;
  OpenChunk current_;
};

}  // namespace slamvdb::recording::ros1
