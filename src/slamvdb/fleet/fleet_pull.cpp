// Pulling a region out of the fleet: PostGIS selects the submaps whose footprint meets it, each
// submap's rows are read and checked by the map file's own row readers (store/submap_payload.hpp).
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <iterator>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"
#include "slamvdb/fleet/fleet_rows.hpp"
#include "slamvdb/store/map_rows.hpp"
#include "slamvdb/store/submap_payload.hpp"

namespace slamvdb::fleet {
namespace {

std::span<const std::byte> bytes_of(const pqxx::binarystring& b) {
  return {reinterpret_cast<const std::byte*>(b.data()), b.size()};
}

// The sessions (first) or the submaps (second) of the keys as a bigint[] / int[] literal.
std::string key_array(const std::optional<std::vector<FleetSubmapKey>>& keys, bool sessions) {
  std::string out = "{";
  if (keys)
    for (const auto& [session, submap] : *keys)
      out += fmt::format("{}{}", out.size() > 1 ? "," : "", sessions ? session : int64_t{submap});
  return out + "}";
}

Pose pose_of(const pqxx::field& f, const std::string& what) { return parse_pose_array(f.c_str(), what); }

}  // namespace

FleetDefinition FleetDatabase::definition() {
  try {
    pqxx::read_transaction tx(connection_->connection);
    if (tx.exec("SELECT to_regclass('slamvdb.fleet') IS NULL")[0][0].as<bool>())
      throw FleetDataError(fmt::format("fleet database {} holds no fleet map (nothing was pushed)", display_url_));
    const pqxx::result r = tx.exec("SELECT params::text FROM slamvdb.fleet");
    if (r.empty()) throw FleetDataError(fmt::format("fleet database {} holds no fleet map (nothing was pushed)", display_url_));
    try {
      return fleet_definition_of(r[0][0].c_str(), fmt::format("fleet database {}", display_url_));
    } catch (const Error& e) {
      throw FleetDataError(e.what());  // the fleet row's parameters are damaged or foreign
    }
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
}

PullReport FleetDatabase::pull(const PullRequest& request, const std::function<void(PulledSubmap&&)>& sink) {
  const auto t0 = std::chrono::steady_clock::now();
  const FleetDefinition fleet = definition();
  PullReport report;
  try {
    // One snapshot for the whole pull: a push or correction meanwhile is seen entirely or not at all.
    pqxx::transaction<pqxx::repeatable_read, pqxx::read_only> tx(connection_->connection);
    const Eigen::AlignedBox3d& b = request.box_fleet;
    const std::string names = text_array(request.sessions);
    const pqxx::result submaps = tx.exec_params(
        "SELECT s.id, s.name, m.submap, m.t_world_submap::text, s.t_fleet_session::text, m.time_begin, m.time_end, "
        "m.path_length, m.blocks, m.known_voxels, m.occupied_voxels, m.semantic_voxels, m.payload_format, m.shard, "
        "s.source, s.robot FROM slamvdb.submaps m JOIN slamvdb.sessions s ON s.id = m.session "
        "WHERE m.shard = ANY($12::integer[]) AND m.footprint && ST_MakeEnvelope($1, $2, $3, $4, 0) "
        "AND m.z_max >= $5 AND m.z_min <= $6 AND ($7 OR s.name = ANY($8::text[])) "
        "AND ($9 OR (m.session, m.submap) IN (SELECT * FROM unnest($10::bigint[], $11::int[]))) "
        "ORDER BY s.id, m.submap",
        b.min().x(), b.min().y(), b.max().x(), b.max().y(), b.min().z(), b.max().z(), request.sessions.empty(), names,
        !request.only.has_value(), key_array(request.only, true), key_array(request.only, false), region_shards(tx, b));
    for (const pqxx::row& row : submaps) {
      const int64_t session = row[0].as<int64_t>();
      const std::string name = row[1].as<std::string>();
      const int id = row[2].as<int>();
      const std::string where = fmt::format("session '{}' submap {}", name, id);
      SubmapSummary summary;
      summary.info.id = id;
      summary.info.T_world_submap = pose_of(row[4], where + " session frame") * pose_of(row[3], where + " anchor");
      if (!row[5].is_null()) summary.info.time_range = {row[5].as<double>(), row[6].as<double>()};
      summary.info.path_length = row[7].as<double>();
      summary.info.finished = true;
      summary.blocks = row[8].as<std::size_t>();
      summary.known_voxels = row[9].as<std::size_t>();
      summary.occupied_voxels = row[10].as<std::size_t>();
      summary.semantic_voxels = row[11].as<std::size_t>();
      const int format = row[12].as<int>();
      const int shard = row[13].as<int>();
      try {
        store::OccupancyRowReader occupancy(id, format, fleet.params);
        for (const pqxx::row& r : tx.exec_params("SELECT bx, by, bz, log_odds, crc FROM slamvdb.occupancy WHERE "
                                                 "session = $1 AND submap = $2 AND shard = $3",
                                                 session, id, shard)) {
          const pqxx::binarystring blob(r[3]);
          occupancy.add(r[0].as<int64_t>(), r[1].as<int64_t>(), r[2].as<int64_t>(), bytes_of(blob), r[4].as<int64_t>());
          ++report.rows, report.payload_bytes += blob.size();
        }
        store::SemanticChunkReader semantics(id, format, fleet.params);
        for (const pqxx::row& r : tx.exec_params("SELECT chunk, keys, counts, embeddings, crc, stats, stats_crc FROM "
                                                 "slamvdb.semantics WHERE session = $1 AND submap = $2 AND shard = $3 "
                                                 "ORDER BY chunk",
                                                 session, id, shard)) {
          const pqxx::binarystring keys(r[1]), counts(r[2]), embeddings(r[3]), stats(r[5]);
          semantics.add(r[0].as<int64_t>(), bytes_of(keys), bytes_of(counts), bytes_of(embeddings), r[4].as<int64_t>(),
                        bytes_of(stats), r[6].as<int64_t>());
          ++report.rows, report.payload_bytes += keys.size() + counts.size() + embeddings.size() + stats.size();
        }
        PulledSubmap pulled{name, id, summary.info,
                            VoxelMap(fleet.params, occupancy.finish(summary), semantics.finish(summary)),
                            row[14].as<std::string>(), row[15].as<std::string>()};
        pulled.info.id = static_cast<int>(report.submaps);  // renumbered: ids of different sessions collide
        sink(std::move(pulled));
      } catch (const Error& e) {
        throw FleetDataError(fmt::format("fleet database {}, {}: {}", display_url_, where, e.what()));
      }
      if (report.sessions.empty() || report.sessions.back() != name) report.sessions.push_back(name);
      ++report.submaps;
    }
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("pull from the fleet database {}", display_url_), e);
  }
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return report;
}

SemanticMap FleetDatabase::pull_map(const PullRequest& request) {
  const FleetDefinition fleet = definition();
  MapInfo info = fleet.info;
  info.source = fmt::format("fleet map {}", display_url_);
  info.sessions.clear();
  std::vector<PulledSubmap> pulled;  // the map is made once its sessions are known
  pull(request, [&](PulledSubmap&& s) {
    assign_pulled_session(info, s);
    pulled.push_back(std::move(s));
  });
  SemanticMap map(fleet.params, info);
  for (PulledSubmap& s : pulled) map.add_finished_submap(s.info, std::move(s.voxels));
  return map;
}

void assign_pulled_session(MapInfo& info, PulledSubmap& submap) {
  auto it = std::find_if(info.sessions.begin(), info.sessions.end(),
                         [&](const SessionInfo& s) { return s.name == submap.session; });
  if (it == info.sessions.end()) {
    info.sessions.push_back({static_cast<int>(info.sessions.size()), submap.session, submap.session_source,
                             submap.session_robot, {}});
    it = std::prev(info.sessions.end());
  }
  submap.info.session = it->id;
}

}  // namespace slamvdb::fleet
