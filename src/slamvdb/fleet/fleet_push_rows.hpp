#pragma once
// Internal to the fleet part: the statements of a push (fleet_push.cpp), shared by
// FleetPushSession (fleet_push_session.cpp). libpqxx stays out of every public header.
#include <optional>
#include <pqxx/pqxx>
#include <string>

#include "slamvdb/fleet/fleet_push.hpp"

namespace slamvdb::fleet {

// Checks the map against the fleet row (Error naming the first entry that differs, before any
// write); with `define`, the first map pushed defines the fleet.
void check_fleet(pqxx::transaction_base& tx, const MapParams& params, const MapInfo& info, bool define,
                 const std::string& display_url);
// A submap's footprint box in the fleet frame from the box of its blocks in its own frame.
Eigen::AlignedBox3d fleet_box(const Eigen::AlignedBox3d& local, const Pose& T_fleet_submap);
// The shard that holds a submap (its home tile's), growing the tile's extent to hold `b`.
int submap_shard(pqxx::work& tx, int64_t session, int submap, const Eigen::AlignedBox3d& b);
// One submap's catalog and payload rows (only what changed since its last push), counted in
// `report`; returns the box of its blocks in its own frame.
Eigen::AlignedBox3d write_submap(pqxx::work& tx, int64_t session, const Submap& submap, const MapParams& params,
                                 const Pose& T_fleet_session, PushReport& report);
// The shard that holds a pushed submap; none when it was never pushed.
std::optional<int> pushed_shard(pqxx::work& tx, int64_t session, int submap);

}  // namespace slamvdb::fleet
