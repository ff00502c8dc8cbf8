// One session's push (FleetPushSession): what `push` does for each submap of a map file and
// `map|slam --push` for each submap as the mapper finishes it, a merge and a loop correction; each
// one transaction.
#include <fmt/format.h>

#include <chrono>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"
#include "slamvdb/fleet/fleet_push_rows.hpp"

namespace slamvdb::fleet {
namespace {

// Runs one transaction of a push; a database failure becomes an Error naming the (redacted) URL.
template <class F>
void in_transaction(pqxx::connection& connection, const std::string& display_url, F&& write) {
  try {
    pqxx::work tx(connection);
    write(tx);
    tx.commit();
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("push to the fleet database {}", display_url), e);
  }
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

FleetPushSession::FleetPushSession(FleetDatabase& fleet, const MapParams& params, const MapInfo& info,
                                   const PushOptions& options)
    : fleet_(fleet), params_(params), options_(options) {
  if (options.session.empty()) throw Error("a push needs a session name");
  fleet.ensure_schema();
  in_transaction(fleet.connection_->connection, fleet.display_url(), [&](pqxx::work& tx) {
    check_fleet(tx, params, info, true, fleet.display_url());
    // The time range starts empty (NULL) and grows with each submap pushed (write_submap).
    const pqxx::row session = tx.exec_params1(
        "INSERT INTO slamvdb.sessions(name, robot, source, t_fleet_session) VALUES ($1, $2, $3, $4::float8[]) "
        "ON CONFLICT (name) DO UPDATE SET robot = EXCLUDED.robot, source = EXCLUDED.source, "
        "t_fleet_session = EXCLUDED.t_fleet_session RETURNING id, xmax = 0",
        options.session, options.robot, info.source, pose_array(options.T_fleet_session));
    report_.session_id = session[0].as<int64_t>();
    report_.session_created = session[1].as<bool>();
  });
}

const std::string& FleetPushSession::display_url() const { return fleet_.display_url(); }

void FleetPushSession::push(const Submap& submap) {
  const auto t0 = std::chrono::steady_clock::now();
  PushReport counts = report_;  // counted once the transaction commits
  Eigen::AlignedBox3d local;
  in_transaction(fleet_.connection_->connection, display_url(), [&](pqxx::work& tx) {
    local = write_submap(tx, report_.session_id, submap, params_, options_.T_fleet_session, counts);
  });
  report_ = counts;
  local_bounds_[submap.info().id] = local;
  report_.seconds += seconds_since(t0);
}

void FleetPushSession::merge(const Submap& target, int source) {
  const auto t0 = std::chrono::steady_clock::now();
  PushReport counts = report_;
  Eigen::AlignedBox3d local;
  in_transaction(fleet_.connection_->connection, display_url(), [&](pqxx::work& tx) {
    local = write_submap(tx, report_.session_id, target, params_, options_.T_fleet_session, counts);
    if (const std::optional<int> shard = pushed_shard(tx, report_.session_id, source)) {
      for (const char* table : {"occupancy", "semantics", "submaps"})
        tx.exec_params(fmt::format("DELETE FROM slamvdb.{} WHERE session = $1 AND submap = $2 AND shard = $3", table),
                       report_.session_id, source, *shard);
      tx.exec_params("DELETE FROM slamvdb.submap_homes WHERE session = $1 AND submap = $2", report_.session_id, source);
      ++counts.submaps_removed;
    }
  });
  report_ = counts;
  local_bounds_[target.info().id] = local;
  local_bounds_.erase(source);
  report_.seconds += seconds_since(t0);
}

void FleetPushSession::move_anchors(const std::map<int, Pose>& T_world_submap) {
  const auto t0 = std::chrono::steady_clock::now();
  int moved = 0;
  in_transaction(fleet_.connection_->connection, display_url(), [&](pqxx::work& tx) {
    for (const auto& [id, T] : T_world_submap) {
      const auto local = local_bounds_.find(id);
      if (local == local_bounds_.end()) continue;  // not pushed yet: it goes with its final anchor
      const Eigen::AlignedBox3d b = fleet_box(local->second, options_.T_fleet_session * T);
      const int shard = submap_shard(tx, report_.session_id, id, b);  // grows its tile's extent
      moved += static_cast<int>(
          tx.exec_params("UPDATE slamvdb.submaps SET t_world_submap = $3::float8[], "
                         "footprint = ST_MakeEnvelope($4, $5, $6, $7, 0), z_min = $8, z_max = $9, "
                         "revision = revision + 1 WHERE session = $1 AND submap = $2 AND shard = $10 "
                         "AND t_world_submap IS DISTINCT FROM $3::float8[]",
                         report_.session_id, id, pose_array(T), b.min().x(), b.min().y(), b.max().x(), b.max().y(),
                         b.min().z(), b.max().z(), shard)
              .affected_rows());
    }
  });
  report_.anchors_moved += moved;
  report_.seconds += seconds_since(t0);
}

void FleetPushSession::set_source(const std::string& source) {
  in_transaction(fleet_.connection_->connection, display_url(), [&](pqxx::work& tx) {
    tx.exec_params("UPDATE slamvdb.sessions SET source = $2 WHERE id = $1", report_.session_id, source);
  });
}

PushReport FleetDatabase::push_map(const SemanticMap& map, const PushOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  FleetPushSession session(*this, map.params(), map.info(), options);
  const std::vector<SubmapInfo> submaps = map.submaps();
  std::size_t done = 0;
  for (const SubmapInfo& info : submaps) {
    map.read_submap(info.id, [&](const Submap& submap) { session.push(submap); });
    if (options.on_submap) options.on_submap(++done, submaps.size());
  }
  PushReport report = session.report();
  report.seconds = seconds_since(t0);
  return report;
}

}  // namespace slamvdb::fleet
