#include "slamvdb/recording/rosbag2_db3.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <cctype>
#include <system_error>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb::recording {

namespace rosbag2_db3_cpp {

// A file: URI for SQLite (RFC 3986: everything but unreserved characters and '/' escaped).
std::string file_uri(const std::filesystem::path& path, const char* query) {
  std::string uri = "file:";
  for (const unsigned char c : path.string()) {
    if (std::isalnum(c) || c == '/' || c == '-' || c == '.' || c == '_' || c == '~')
      uri += static_cast<char>(c);
    else
      uri += fmt::format("%{:02X}", c);
  }
  return uri + query;
}

Serialization serialization_of(const std::string& format) {
  if (format == "cdr") return Serialization::kCdr;
  if (format == "ros1") return Serialization::kRos1;
  return Serialization::kOther;
}

std::string text_column(sqlite3_stmt* statement, int column) {
  const unsigned char* text = sqlite3_column_text(statement, column);
  return text ? std::string(reinterpret_cast<const char*>(text), static_cast<std::size_t>(sqlite3_column_bytes(statement, column)))
              : std::string();
}

// Finalizes a statement at the end of a scope.
struct StatementGuard {
  sqlite3_stmt* statement;
  ~StatementGuard() { sqlite3_finalize(statement); }
};

}  // namespace rosbag2_db3_cpp
using namespace rosbag2_db3_cpp;

Db3Reader::Db3Reader(const std::filesystem::path& path, std::string display) : display_(std::move(display)) {
  {
    RegularFile file(path, "ROS 2 bag file");  // a FIFO or a folder is a clear Error; nothing left open
    size_ = file.size();
  }
  // A bag recorded in WAL mode and not closed keeps its last messages in the -wal file, which an
  // immutable open would not see.
  std::error_code ec;
  const bool has_wal = std::filesystem::file_size(path.string() + "-wal", ec) > 0 && !ec;
  const std::string uri = file_uri(path, has_wal ? "?mode=ro" : "?immutable=1");
  const int rc = sqlite3_open_v2(uri.c_str(), &db_, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
  if (rc != SQLITE_OK) {
    const std::string message = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
    sqlite3_close(db_);
    db_ = nullptr;
    throw Error(fmt::format("cannot open {} as an SQLite database: {}", display_, message));
  }
  if (has_wal) notes_.push_back(fmt::format("{} has a write-ahead log (-wal file): read with it", display_));
  try {
    bool topics = false, messages = false, definitions = false;
    {
      sqlite3_stmt* s = prepare("SELECT name FROM sqlite_master WHERE type = 'table'");
      StatementGuard guard{s};
      int step = 0;
      while ((step = sqlite3_step(s)) == SQLITE_ROW) {
        const std::string name = text_column(s, 0);
        topics |= name == "topics";
        messages |= name == "messages";
        definitions |= name == "message_definitions";
      }
      if (step != SQLITE_DONE) fail(step, "listing its tables");
    }
    if (!topics || !messages)
      throw Error(fmt::format("{} is an SQLite database but not a ROS 2 bag: it has no {} table", display_,
                              topics ? "messages" : "topics"));
    std::map<std::string, std::string> definition_of_type;
    if (definitions) {
      sqlite3_stmt* s = prepare("SELECT topic_type, encoded_message_definition FROM message_definitions");
      StatementGuard guard{s};
      int step = 0;
      while ((step = sqlite3_step(s)) == SQLITE_ROW) definition_of_type[text_column(s, 0)] = text_column(s, 1);
      if (step != SQLITE_DONE) fail(step, "reading its message definitions");
    }
    sqlite3_stmt* s = prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id");
    StatementGuard guard{s};
    int step = 0;
    while ((step = sqlite3_step(s)) == SQLITE_ROW) {
      Channel c;
      c.id = static_cast<std::uint32_t>(channels_.size());
      c.topic = text_column(s, 1);
      const std::string type = text_column(s, 2);
      c.type = ros1_type_name(type);
      c.encoding = text_column(s, 3);
      c.serialization = serialization_of(c.encoding);
      if (const auto d = definition_of_type.find(type); d != definition_of_type.end()) c.definition = d->second;
      if (!channel_of_topic_.emplace(sqlite3_column_int64(s, 0), channels_.size()).second)
        throw Error(fmt::format("{}: two topics have the id {}: damaged", display_, sqlite3_column_int64(s, 0)));
      channels_.push_back(std::move(c));
    }
    if (step != SQLITE_DONE) fail(step, "reading its topics");
    start_query();
  } catch (...) {
    sqlite3_finalize(query_);
    sqlite3_close(db_);
    throw;
  }
}

Db3Reader::~Db3Reader() {
  sqlite3_finalize(query_);
  sqlite3_close(db_);
}

sqlite3_stmt* Db3Reader::prepare(const std::string& sql) const {
  sqlite3_stmt* statement = nullptr;
  const int rc = sqlite3_prepare_v2(db_, sql.c_str(), -1, &statement, nullptr);
  if (rc != SQLITE_OK) {
    sqlite3_finalize(statement);
    fail(rc, "preparing \"" + sql + "\"");
  }
  return statement;
}

void Db3Reader::fail(int rc, const std::string& doing) const {
  const std::string message = sqlite3_errmsg(db_), code = sqlite3_errstr(rc);
  throw Error(fmt::format("{}: SQLite says \"{}\"{} while {}: the file is damaged or not a ROS 2 bag", display_, message,
                          message == code ? "" : " (" + code + ")", doing));
}

void Db3Reader::start_query() {
  sqlite3_finalize(query_);
  query_ = nullptr;
  std::string sql = "SELECT id, topic_id, timestamp, data FROM messages";
  std::vector<std::string> conditions;
  if (resumed_)
    conditions.push_back("(timestamp > ?1 OR (timestamp = ?1 AND id > ?2))");
  if (!selected_.empty()) {
    std::string ids;
    for (const auto& [topic_id, channel] : channel_of_topic_)
      if (selected_.count(static_cast<std::uint32_t>(channel))) {
        if (!ids.empty()) ids += ',';
        ids += std::to_string(topic_id);
      }
    conditions.push_back("topic_id IN (" + ids + ")");
  }
  for (std::size_t i = 0; i < conditions.size(); ++i) sql += (i == 0 ? " WHERE " : " AND ") + conditions[i];
  sql += " ORDER BY timestamp, id";
  query_ = prepare(sql);
  if (resumed_) {
    sqlite3_bind_int64(query_, 1, last_timestamp_);
    sqlite3_bind_int64(query_, 2, last_id_);
  }
}

void Db3Reader::select(const std::set<std::uint32_t>& channel_ids) {
  selected_.clear();
  for (const std::uint32_t id : channel_ids)
    if (id < channels_.size()) selected_.insert(id);
  if (!channel_ids.empty() && selected_.empty()) selected_.insert(UINT32_MAX);  // none of this file's
  // The new query starts at the next call to next(): the message handed out last points into the
  // current one's row, and stays valid until then.
  restart_ = !at_end_;
}

bool Db3Reader::next(Message& out) {
  if (at_end_) return false;
  if (restart_) {
    start_query();
    restart_ = false;
  }
  const int rc = sqlite3_step(query_);
  if (rc == SQLITE_DONE) {
    at_end_ = true;
    bytes_read_ = size_;
    return false;
  }
  if (rc != SQLITE_ROW) fail(rc, fmt::format("reading its messages (after message {})", delivered_));
  resumed_ = true;
  last_id_ = sqlite3_column_int64(query_, 0);
  const std::int64_t topic_id = sqlite3_column_int64(query_, 1);
  last_timestamp_ = sqlite3_column_int64(query_, 2);
  const auto channel = channel_of_topic_.find(topic_id);
  if (channel == channel_of_topic_.end())
    throw Error(fmt::format("{}: message {} (row id {}) is on topic id {}, which the topics table does not list: "
                            "damaged",
                            display_, delivered_, last_id_, topic_id));
  const void* blob = sqlite3_column_blob(query_, 3);
  const int bytes = sqlite3_column_bytes(query_, 3);
  out.channel = &channels_[channel->second];
  out.log_time_ns = last_timestamp_;
  out.data = blob ? std::span<const std::uint8_t>(static_cast<const std::uint8_t*>(blob), static_cast<std::size_t>(bytes))
                  : std::span<const std::uint8_t>();
  out.index = delivered_++;
  return true;
}

std::optional<TimeRange> Db3Reader::time_range() const {
  sqlite3_stmt* s = prepare("SELECT MIN(timestamp), MAX(timestamp) FROM messages");
  StatementGuard guard{s};
  const int rc = sqlite3_step(s);
  if (rc != SQLITE_ROW) fail(rc, "reading its time range");
  if (sqlite3_column_type(s, 0) == SQLITE_NULL) return std::nullopt;
  return TimeRange{sqlite3_column_int64(s, 0), sqlite3_column_int64(s, 1)};
}

void Db3Reader::count_messages() {
  for (Channel& c : channels_) c.message_count = 0;
  sqlite3_stmt* s = prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id");
  StatementGuard guard{s};
  int rc = 0;
  while ((rc = sqlite3_step(s)) == SQLITE_ROW)
    if (const auto c = channel_of_topic_.find(sqlite3_column_int64(s, 0)); c != channel_of_topic_.end())
      channels_[c->second].message_count = static_cast<std::uint64_t>(sqlite3_column_int64(s, 1));
  if (rc != SQLITE_DONE) fail(rc, "counting its messages");
}

}  // namespace slamvdb::recording
