// Splitting a fleet by region across servers with PostgreSQL's own means (docs/fleet-design.md,
// "Scale out"): on the coordinator, `submaps`, `occupancy` and `semantics` are partitioned by the
// shard id, each partition a postgres_fdw foreign table on a shard server; sessions, the fleet
// row, the tiles and the submaps' home tiles stay on the coordinator.
#include <fmt/format.h>
#include <libpq-fe.h>

#include <regex>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"

namespace slamvdb::fleet {
namespace {

// Serialises add_shard on one coordinator (two at once would pick the same id).
constexpr long long kShardsLockKey = 0x736c616d76646232;  // "slamvdb2"

// A libpq connection string's options split as postgres_fdw takes them: the server's (host, port,
// dbname, ssl settings, ...) and the user mapping's (user, password). Without a connect_timeout a
// dead shard's host could hold a query for minutes: 5 s unless the URL says otherwise.
struct ShardFdwOptions {
  std::vector<std::pair<std::string, std::string>> server, user;
};

ShardFdwOptions shard_fdw_options(const std::string& url, const std::string& display_url) {
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(url.c_str(), &error);
  if (!options) {
    const std::string reason = error ? trimmed_message(error) : "out of memory";
    if (error) PQfreemem(error);
    throw Error(fmt::format("shard connection string {}: {}", display_url, reason));
  }
  ShardFdwOptions out;
  bool timeout = false;
  for (const PQconninfoOption* o = options; o->keyword; ++o) {
    if (!o->val || !*o->val) continue;
    const std::string key = o->keyword;
    if (key == "user" || key == "password" || key == "sslpassword") {
      out.user.emplace_back(key, o->val);
    } else if (key != "client_encoding" && key != "fallback_application_name" && key != "replication") {
      out.server.emplace_back(key, o->val);  // the three skipped ones postgres_fdw sets itself
      timeout |= key == "connect_timeout";
    }
  }
  PQconninfoFree(options);
  if (!timeout) out.server.emplace_back("connect_timeout", "5");
  out.server.emplace_back("extensions", "postgis");  // PostGIS conditions are evaluated on the shard
  return out;
}

// A string literal for DDL, which takes no parameters (standard_conforming_strings: quotes doubled).
std::string shard_sql_literal(pqxx::transaction_base& tx, const std::string& value) {
  return fmt::format("'{}'", tx.esc(value));
}

std::string fdw_option_list(pqxx::transaction_base& tx, const std::vector<std::pair<std::string, std::string>>& options) {
  std::string out;
  for (const auto& [key, value] : options)
    out += fmt::format("{}{} {}", out.empty() ? "" : ", ", tx.quote_name(key), shard_sql_literal(tx, value));
  return out;
}

// An empty coordinator's three tables become partitioned tables of the same columns and checks
// (no keys or indexes: a foreign partition holds none; each shard keeps its own).
void partition_coordinator(pqxx::transaction_base& tx) {
  for (const char* table : {"submaps", "occupancy", "semantics"})
    tx.exec(fmt::format("ALTER TABLE slamvdb.{0} RENAME TO {0}_unsharded", table));
  for (const char* table : {"submaps", "occupancy", "semantics"})
    tx.exec(fmt::format("CREATE TABLE slamvdb.{0} (LIKE slamvdb.{0}_unsharded INCLUDING DEFAULTS INCLUDING CONSTRAINTS) "
                        "PARTITION BY LIST (shard)",
                        table));
  tx.exec("DROP TABLE slamvdb.occupancy_unsharded, slamvdb.semantics_unsharded, slamvdb.submaps_unsharded");
}

}  // namespace

std::vector<std::pair<int, std::string>> FleetDatabase::shards() {
  std::vector<std::pair<int, std::string>> out;
  try {
    pqxx::read_transaction tx(connection_->connection);
    if (tx.exec("SELECT to_regclass('slamvdb.shards') IS NULL")[0][0].as<bool>()) return out;
    for (const pqxx::row& row : tx.exec("SELECT id, name FROM slamvdb.shards ORDER BY id"))
      out.emplace_back(row[0].as<int>(), row[1].as<std::string>());
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
  return out;
}

int FleetDatabase::add_shard(const std::string& name, const std::string& shard_url) {
  if (!std::regex_match(name, std::regex("[a-z][a-z0-9_]{0,39}")))
    throw Error(fmt::format("shard name '{}': use a lower-case letter then up to 39 lower-case letters, digits or _", name));
  const std::string shard_display = redact_connection_url(shard_url);
  const ShardFdwOptions options = shard_fdw_options(shard_url, shard_display);
  ensure_schema();
  int id = 0;
  try {
    pqxx::work tx(connection_->connection);
    tx.exec_params("SELECT pg_advisory_xact_lock($1)", kShardsLockKey);
    if (!tx.exec("SELECT relkind = 'p' FROM pg_class WHERE oid = 'slamvdb.submaps'::regclass")[0][0].as<bool>()) {
      if (tx.exec("SELECT EXISTS (SELECT FROM slamvdb.submaps)")[0][0].as<bool>())
        throw Error(fmt::format("fleet database {} holds submaps in its own tables: a fleet is sharded from its "
                                "creation (pull its regions and push them into a new, sharded fleet)",
                                display_url_));
      partition_coordinator(tx);
    }
    if (!tx.exec_params("SELECT id FROM slamvdb.shards WHERE name = $1", name).empty())
      throw Error(fmt::format("fleet database {} already has a shard named '{}'", display_url_, name));
    id = tx.exec("SELECT coalesce(max(id), 0) + 1 FROM slamvdb.shards")[0][0].as<int>();

    // The shard's tables: the fleet schema made by ensure_schema (so a shard migrates as a fleet
    // does), without what only the coordinator holds. Committed before the coordinator's part;
    // a failed add_shard leaves an empty shard that a repeated add_shard takes over.
    FleetDatabase shard(shard_url);
    shard.ensure_schema();
    {
      pqxx::work stx(shard.connection_->connection);
      if (!stx.exec("SELECT to_regclass('slamvdb.sessions') IS NULL")[0][0].as<bool>()) {
        if (stx.exec("SELECT EXISTS (SELECT FROM slamvdb.sessions) OR EXISTS (SELECT FROM slamvdb.fleet)")[0][0].as<bool>())
          throw Error(fmt::format("shard database {} holds a fleet map of its own: a shard must start empty", shard_display));
        stx.exec("DROP TABLE slamvdb.submap_homes, slamvdb.tiles, slamvdb.shards, slamvdb.fleet");
        stx.exec("DROP TABLE slamvdb.sessions CASCADE");  // and the submaps' key into it
      } else if (stx.exec("SELECT EXISTS (SELECT FROM slamvdb.submaps)")[0][0].as<bool>()) {
        throw Error(fmt::format("shard database {} is already a shard holding submaps (of another fleet?)", shard_display));
      }
      // Rows reach a shard only through its partition, so each holds its own id alone.
      stx.exec(fmt::format("ALTER TABLE slamvdb.submaps DROP CONSTRAINT IF EXISTS submaps_shard_id, "
                           "ADD CONSTRAINT submaps_shard_id CHECK (shard = {})",
                           id));
      stx.exec(fmt::format("COMMENT ON SCHEMA slamvdb IS {}",
                           shard_sql_literal(stx, fmt::format("shard '{}' (id {}) of the slamvdb fleet map at {}: sessions and the "
                                                 "fleet definition are on that coordinator",
                                                 name, id, display_url_))));
      stx.commit();
    }

    // Identifiers cannot be parameters: the name is checked above and option values are quoted.
    const std::string server = "slamvdb_shard_" + name;
    tx.exec("CREATE EXTENSION IF NOT EXISTS postgres_fdw");
    tx.exec(fmt::format("CREATE SERVER {} FOREIGN DATA WRAPPER postgres_fdw OPTIONS ({})", server,
                        fdw_option_list(tx, options.server)));
    tx.exec(fmt::format("CREATE USER MAPPING FOR PUBLIC SERVER {}{}", server,
                        options.user.empty() ? "" : " OPTIONS (" + fdw_option_list(tx, options.user) + ")"));
    for (const char* table : {"submaps", "occupancy", "semantics"})
      tx.exec(fmt::format("CREATE FOREIGN TABLE slamvdb.{0}_{1} PARTITION OF slamvdb.{0} FOR VALUES IN ({2}) "
                          "SERVER {3} OPTIONS (schema_name 'slamvdb', table_name '{0}')",
                          table, name, id, server));
    tx.exec_params("INSERT INTO slamvdb.shards(id, name, server) VALUES ($1, $2, $3)", id, name, server);
    tx.commit();
  } catch (const Error&) {
    throw;
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("adding shard '{}' ({}) to the fleet database {}", name, shard_display, display_url_), e);
  }
  return id;
}

}  // namespace slamvdb::fleet
