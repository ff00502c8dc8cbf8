#pragma once
// One .db3 file of a ROS 2 bag (rosbag2's sqlite3 storage), read with SQLite's C API. The tables
// rosbag2 writes: topics(id, name, type, serialization_format, offered_qos_profiles
// [, type_description_hash]), messages(id, topic_id, timestamp, data) with an index on timestamp,
// and, from schema version 4 (Iron), message_definitions(topic_type, encoding,
// encoded_message_definition, ...). Messages come out ordered by (timestamp, id): the order
// rosbag2 itself reads them in, equal times in the order they were written. Opened read-only
// without locking (immutable), so a bag on a read-only medium reads and no -shm/-wal files appear.
// Why not store/sqlite_db.hpp's Database/Statement (which recording/ may not link: store/ is a
// later part): the overlap is a guard that finalizes a statement and a column-to-string helper
// (~20 lines), while the error models differ. The map store's errors speak of a slamvdb map
// ("not an SQLite database, so not a slamvdb map") and carry no context; every error here names
// the bag file and what was being done, and a damaged bag is not a damaged map. A shared wrapper in
// its own part would need an error-wording hook at each call and would hold the long-lived, resumable
// message query in an optional: more code than it removes. Revisit if a third SQLite reader appears.
#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

class Db3Reader final : public RecordingReader {
 public:
  // `display` names the file in messages (the .db3.zstd it came from, for a decompressed copy).
  Db3Reader(const std::filesystem::path& path, std::string display);
  ~Db3Reader() override;
  Db3Reader(const Db3Reader&) = delete;
  Db3Reader& operator=(const Db3Reader&) = delete;

  std::string describe() const override { return "ROS 2 bag file (sqlite3)"; }
  // Channel ids are the topics table's ids; message counts are not known (counted on demand by
  // count_messages()).
  const std::vector<Channel>& channels() const override { return channels_; }
  std::optional<TimeRange> time_range() const override;
  std::uint64_t size_bytes() const override { return size_; }
  void select(const std::set<std::uint32_t>& channel_ids) override;
  bool next(Message& out) override;
  // The file's size once it has been read to the end (SQLite reads pages in index order, not the
  // file front to back): progress by message is what a caller can show.
  std::uint64_t bytes_read() const override { return bytes_read_; }
  std::vector<std::string> notes() const override { return notes_; }

  // Fills Channel::message_count from the messages table (one pass over its rows, not their data).
  void count_messages();

 private:
  sqlite3_stmt* prepare(const std::string& sql) const;
  [[noreturn]] void fail(int rc, const std::string& doing) const;
  void start_query();

  std::string display_;
  std::uint64_t size_ = 0, bytes_read_ = 0;
  sqlite3* db_ = nullptr;
  sqlite3_stmt* query_ = nullptr;
  std::vector<Channel> channels_;
  std::map<std::int64_t, std::size_t> channel_of_topic_;  // topics.id -> index in channels_
  std::set<std::uint32_t> selected_;
  bool restart_ = false;  // select() was called: a new query from the next message on
  bool resumed_ = false;  // a message was read: a new query starts after (last_timestamp_, last_id_)
  std::int64_t last_timestamp_ = 0, last_id_ = 0;
  std::uint64_t delivered_ = 0;
  bool at_end_ = false;
  std::vector<std::string> notes_;
};

}  // namespace slamvdb::recording
