// The fleet's catalog as a whole (FleetDatabase::catalog): sessions and submaps without payloads,
// what `serve --db` answers on GET /api/info and /api/submaps.
#include <fmt/format.h>

#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"
#include "slamvdb/fleet/fleet_rows.hpp"

namespace slamvdb::fleet {
namespace {

std::optional<std::pair<double, double>> time_range_of(const pqxx::field& begin, const pqxx::field& end) {
  if (begin.is_null() || end.is_null()) return std::nullopt;
  return std::pair{begin.as<double>(), end.as<double>()};
}

}  // namespace

FleetCatalog FleetDatabase::catalog() {
  FleetCatalog out;
  try {
    // One snapshot: a push meanwhile is seen entirely or not at all.
    pqxx::transaction<pqxx::repeatable_read, pqxx::read_only> tx(connection_->connection);
    std::map<int64_t, std::size_t> session_at;
    for (const pqxx::row& row : tx.exec("SELECT id, name, robot, source, time_begin, time_end, t_fleet_session::text "
                                        "FROM slamvdb.sessions ORDER BY id")) {
      CatalogSession s;
      s.id = row[0].as<int64_t>();
      s.name = row[1].as<std::string>();
      s.robot = row[2].as<std::string>();
      s.source = row[3].as<std::string>();
      s.time_range = time_range_of(row[4], row[5]);
      s.T_fleet_session = parse_pose_array(row[6].c_str(), fmt::format("session '{}' frame", s.name));
      session_at[s.id] = out.sessions.size();
      out.sessions.push_back(std::move(s));
    }
    for (const pqxx::row& row : tx.exec(
             "SELECT session, submap, t_world_submap::text, time_begin, time_end, path_length, blocks, known_voxels, "
             "occupied_voxels, semantic_voxels, revision, ST_XMin(footprint), ST_YMin(footprint), z_min, "
             "ST_XMax(footprint), ST_YMax(footprint), z_max FROM slamvdb.submaps ORDER BY session, submap")) {
      const auto at = session_at.find(row[0].as<int64_t>());
      if (at == session_at.end()) continue;  // cannot be (a foreign key); not worth a refusal
      CatalogSession& session = out.sessions[at->second];
      CatalogSubmap m;
      m.session = session.name;
      m.id = row[1].as<int>();
      m.T_fleet_submap = session.T_fleet_session *
                         parse_pose_array(row[2].c_str(), fmt::format("session '{}' submap {} anchor", m.session, m.id));
      m.time_range = time_range_of(row[3], row[4]);
      m.path_length = row[5].as<double>();
      m.blocks = row[6].as<std::size_t>();
      m.known_voxels = row[7].as<std::size_t>();
      m.occupied_voxels = row[8].as<std::size_t>();
      m.semantic_voxels = row[9].as<std::size_t>();
      m.revision = row[10].as<int>();
      m.bounds_fleet = Eigen::AlignedBox3d(Vec3d(row[11].as<double>(), row[12].as<double>(), row[13].as<double>()),
                                           Vec3d(row[14].as<double>(), row[15].as<double>(), row[16].as<double>()));
      ++session.submaps;
      out.submaps.push_back(std::move(m));
    }
  } catch (const pqxx::failure& e) {
    throw Error(fmt::format("fleet database {}: {}{}", display_url_, trimmed_message(e.what()), shard_hint(e.what())));
  }
  return out;
}

}  // namespace slamvdb::fleet
