// The fleet's catalog as a whole (FleetDatabase::catalog): sessions and submaps without payloads,
// what `serve --db` answers on GET /api/info and /api/submaps.
#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"

namespace slamvdb::fleet {

std::size_t FleetDatabase::semantic_voxels() {
  try {
    pqxx::read_transaction tx(connection_->connection);
    return tx.exec("SELECT coalesce(sum(semantic_voxels), 0)::bigint FROM slamvdb.submaps")[0][0].as<std::size_t>();
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
}

FleetCatalog FleetDatabase::catalog() {
  pqxx::result sessions, submaps;
  try {
    // One snapshot: a push meanwhile is seen entirely or not at all.
    pqxx::transaction<pqxx::repeatable_read, pqxx::read_only> tx(connection_->connection);
    sessions = tx.exec("SELECT id, name, robot, source, time_begin, time_end, t_fleet_session::text "
                       "FROM slamvdb.sessions ORDER BY id");
    submaps = tx.exec(
        "SELECT session, submap, t_world_submap::text, time_begin, time_end, path_length, blocks, known_voxels, "
        "occupied_voxels, semantic_voxels, revision, ST_XMin(footprint), ST_YMin(footprint), z_min, "
        "ST_XMax(footprint), ST_YMax(footprint), z_max FROM slamvdb.submaps ORDER BY session, submap");
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
  // The rows decoded as text by catalog_of (fleet_catalog_rows.hpp, fuzzed without a database).
  const auto text_rows = [](const pqxx::result& result) {
    std::vector<TextRow> rows;
    rows.reserve(result.size());
    for (const pqxx::row& row : result) rows.push_back(text_row(row));
    return rows;
  };
  try {
    return catalog_of(text_rows(sessions), text_rows(submaps));
  } catch (const Error& e) {
    throw FleetDataError(fmt::format("fleet database {}: {}", display_url_, e.what()));
  }
}

}  // namespace slamvdb::fleet
