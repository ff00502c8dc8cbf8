#pragma once
// Internal to the fleet part: the libpq connection behind a FleetDatabase, and the helpers its
// statements share (libpqxx stays out of every public header).
#include <fmt/format.h>

#include <pqxx/pqxx>
#include <string>

#include "slamvdb/core/types.hpp"
#include "slamvdb/fleet/fleet_catalog_rows.hpp"
#include "slamvdb/fleet/fleet_database.hpp"

namespace slamvdb::fleet {

struct FleetDatabase::Connection {
  pqxx::connection connection;
  explicit Connection(const std::string& url) : connection(url) {}
};

// A pose as a PostgreSQL float8[] literal of its 16 entries, row-major (exact: 17 digits).
inline std::string pose_array(const Pose& T) {
  std::string out = "{";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) out += fmt::format("{}{:.17g}", r + c == 0 ? "" : ",", T.matrix()(r, c));
  return out + "}";
}

// A text[] literal: each element double-quoted, backslash and quote escaped.
inline std::string text_array(const std::vector<std::string>& items) {
  std::string out = "{";
  for (const std::string& item : items) {
    out += out.size() > 1 ? ",\"" : "\"";
    for (const char c : item) {
      if (c == '"' || c == '\\') out += '\\';
      out += c;
    }
    out += '"';
  }
  return out + "}";
}

// The shards whose tiles' extents meet the region, as an int[] literal for `shard = ANY(...)`: on a
// sharded fleet the planner then prunes every other shard's partition, so a region never opens a
// connection to a server that holds none of it (a dead one included).
inline std::string region_shards(pqxx::transaction_base& tx, const Eigen::AlignedBox3d& b) {
  return tx
      .exec_params("SELECT coalesce(array_agg(DISTINCT shard ORDER BY shard), '{}')::text FROM slamvdb.tiles "
                   "WHERE x_min <= $3 AND x_max >= $1 AND y_min <= $4 AND y_max >= $2",
                   b.min().x(), b.min().y(), b.max().x(), b.max().y())[0][0]
      .c_str();
}

// A shard's server could not be reached (postgres_fdw names the foreign server it failed on).
inline std::string shard_hint(const std::string& message) {
  return message.find("server \"slamvdb_shard_") != std::string::npos
             ? " (a shard of this fleet is down: regions on other shards still answer)"
             : "";
}

inline std::string trimmed_message(std::string text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text;
}

// A row's fields as text (views into `row`'s result, which must outlive them), NULL as nullopt.
inline TextRow text_row(const pqxx::row& row) {
  TextRow out;
  out.reserve(row.size());
  for (const pqxx::field& f : row)
    out.push_back(f.is_null() ? std::nullopt : std::optional<std::string_view>(std::string_view(f.c_str(), f.size())));
  return out;
}

// libpqxx's failure `e` as the fleet's FleetDatabaseError: "`where`: the server's reason" (with the
// shard hint when a shard's server failed); a lost connection is told from a failed statement.
inline FleetDatabaseError database_error(const std::string& where, const pqxx::failure& e) {
  const bool lost = dynamic_cast<const pqxx::broken_connection*>(&e) != nullptr;
  return FleetDatabaseError(lost ? FleetDatabaseError::Kind::kConnectionLost : FleetDatabaseError::Kind::kStatementFailed,
                            fmt::format("{}: {}{}", where, trimmed_message(e.what()), shard_hint(e.what())));
}

}  // namespace slamvdb::fleet
