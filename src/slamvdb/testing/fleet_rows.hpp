#pragma once
// For the fleet tests that compare two fleets (one pushed while mapping, one pushed from the
// finished map file): a digest of every row of the fleet's tables, read with psql.
#include <string>

#include "slamvdb/testing/postgres_server.hpp"

namespace slamvdb::testing {

// Every row of the fleet's tables (a digest per table, and the row counts), without what names a
// push rather than the map: ids are the same in two fresh databases; `revision` counts the catalog
// rewrites, so it is compared apart. A tile's extent only grows (docs/fleet-design.md, "Scale
// out"), so a fleet pushed while mapping may hold wider tiles than the file's: with_tiles = false.
inline std::string fleet_rows(PostgresServer& server, const std::string& db, bool with_tiles = true) {
  const auto digest = [](const std::string& select) {
    return "(SELECT count(*) || ':' || coalesce(md5(string_agg(x::text, ',' ORDER BY x::text)), '') FROM (" + select +
           ") x)";
  };
  return psql_value(
      server,
      "SELECT concat_ws(' | ', " +
          digest("SELECT voxel_size, semantic_dim, model_id, ontology, params FROM slamvdb.fleet") + ", " +
          digest("SELECT id, name, robot, source, time_begin, time_end, t_fleet_session FROM slamvdb.sessions") +
          ", " +
          digest("SELECT session, submap, t_world_submap, time_begin, time_end, path_length, ST_AsText(footprint), "
                 "z_min, z_max, blocks, known_voxels, occupied_voxels, semantic_voxels, payload_format, payload_crc, "
                 "payload_bytes, embedding_centroid, embedding_radius, shard FROM slamvdb.submaps") +
          ", " + digest("SELECT * FROM slamvdb.occupancy") + ", " + digest("SELECT * FROM slamvdb.semantics") + ", " +
          digest("SELECT * FROM slamvdb.submap_homes") + ", " +
          (with_tiles ? digest("SELECT * FROM slamvdb.tiles") : "''") + ")",
      db);
}

}  // namespace slamvdb::testing
