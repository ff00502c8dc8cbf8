#include "slamvdb/fleet/fleet_database.hpp"

#include <fmt/format.h>

#include <pqxx/pqxx>
#include <regex>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"
#include "slamvdb/fleet/fleet_schema.hpp"

namespace slamvdb::fleet {
namespace {

// Any number, the same in every slamvdb: the key of the advisory lock that serialises schema
// creation and migration (CREATE EXTENSION and CREATE SCHEMA race when two robots start at once).
constexpr long long kSchemaLockKey = 0x736c616d76646231;  // "slamvdb1"

int read_schema_version(pqxx::transaction_base& tx, const std::string& display_url) {
  if (tx.exec("SELECT to_regclass('slamvdb.schema_info') IS NULL")[0][0].as<bool>()) {
    if (!tx.exec("SELECT to_regnamespace('slamvdb') IS NULL")[0][0].as<bool>())
      throw FleetDataError(fmt::format("fleet database {}: schema `slamvdb` exists without its version table "
                              "(a damaged or foreign schema; not touched)",
                              display_url));
    return 0;
  }
  const pqxx::result r = tx.exec("SELECT version FROM slamvdb.schema_info");
  if (r.size() != 1 || r[0][0].is_null())
    throw FleetDataError(fmt::format("fleet database {}: slamvdb.schema_info holds {} rows, expected one version (damaged; "
                            "not touched)",
                            display_url, r.size()));
  return r[0][0].as<int>();
}

}  // namespace

std::string redact_connection_url(std::string_view url) {
  std::string out(url);
  // URL form: scheme://user:password@host -> scheme://user:***@host; parameter forms
  // (key=value and ?password=...) -> password=***.
  out = std::regex_replace(out, std::regex(R"(^(postgres(?:ql)?://[^:/@?]*):[^@/?]*@)"), "$1:***@");
  out = std::regex_replace(out, std::regex(R"((^|[\s?&])password=('[^']*'|[^\s&]*))"), "$1password=***");
  return out;
}

FleetDatabase::FleetDatabase(const std::string& url) : display_url_(redact_connection_url(url)) {
  try {
    connection_ = std::make_unique<Connection>(url);
  } catch (const std::exception& e) {
    throw FleetDatabaseError(FleetDatabaseError::Kind::kUnreachable,
                             fmt::format("cannot connect to the fleet database {}: {}", display_url_, trimmed_message(e.what())));
  }
}

FleetDatabase::~FleetDatabase() = default;
FleetDatabase::FleetDatabase(FleetDatabase&&) noexcept = default;
FleetDatabase& FleetDatabase::operator=(FleetDatabase&&) noexcept = default;

int FleetDatabase::schema_version() {
  try {
    pqxx::read_transaction tx(connection_->connection);
    return read_schema_version(tx, display_url_);
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
}

SchemaCheck FleetDatabase::ensure_schema() {
  SchemaCheck check;
  try {
    pqxx::work tx(connection_->connection);
    tx.exec_params("SELECT pg_advisory_xact_lock($1)", kSchemaLockKey);
    check.found_version = read_schema_version(tx, display_url_);
    if (check.found_version > kFleetSchemaVersion)
      throw Error(fmt::format("fleet database {} has schema version {}, newer than this slamvdb's {}: use a newer "
                              "slamvdb (an older one must not write rows it does not understand)",
                              display_url_, check.found_version, kFleetSchemaVersion));
    if (check.found_version == 0) {
      try {
        pqxx::subtransaction sub(tx, "postgis");
        sub.exec("CREATE EXTENSION IF NOT EXISTS postgis");
        sub.commit();
      } catch (const pqxx::sql_error& e) {
        throw Error(fmt::format("fleet database {}: cannot create the PostGIS extension ({}); the server needs "
                                "PostGIS installed (Debian: postgresql-15-postgis-3) and a role allowed to create it",
                                display_url_, trimmed_message(e.what())));
      }
    }
    const std::span<const char* const> steps = fleet_migrations();
    for (int v = check.found_version; v < kFleetSchemaVersion; ++v) tx.exec(steps[static_cast<std::size_t>(v)]);
    if (check.found_version != kFleetSchemaVersion)
      tx.exec_params(
          "INSERT INTO slamvdb.schema_info(version) VALUES ($1) ON CONFLICT (single) DO UPDATE SET version = $1",
          kFleetSchemaVersion);
    tx.commit();
  } catch (const Error&) {
    throw;
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
  check.version = kFleetSchemaVersion;
  return check;
}

}  // namespace slamvdb::fleet
