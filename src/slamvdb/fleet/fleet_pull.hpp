#pragma once
// What a pull from the fleet map takes and gives (FleetDatabase::pull): the submaps of a region,
// from every session or the named ones, in the fleet frame.
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/fleet/fleet_summary.hpp"

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::fleet {

// A submap's key in the fleet: (session id, submap id in its session).
using FleetSubmapKey = std::pair<int64_t, int>;

struct PullRequest {
  Eigen::AlignedBox3d box_fleet;      // the region (fleet frame, metres): submaps whose footprint meets it
  std::vector<std::string> sessions{};  // empty: every session
  std::optional<std::vector<FleetSubmapKey>> only{};  // given: of those, only these submaps
};

// A submap of a region as the catalog describes it, without its payload: where it lies (fleet
// frame) and its summary (none for rows pushed before schema version 2).
struct RegionSubmap {
  FleetSubmapKey key;
  Eigen::AlignedBox3d bounds_fleet;
  std::optional<EmbeddingCap> cap;
  std::size_t semantic_voxels = 0;  // 0: no embedding, nothing to classify or find
};

// One submap as pulled: renumbered (ids of different sessions collide), anchored in the fleet
// frame (T_fleet_session * T_world_submap), with where it came from.
struct PulledSubmap {
  std::string session;
  int session_submap_id = 0;
  SubmapInfo info;
  VoxelMap voxels;
  std::string session_source, session_robot;  // the fleet's sessions row
};

// Gives a pulled submap its session in the map being built: the fleet's session of that name,
// added to `info.sessions` (numbered in pull order, with its source and robot) when it is new, so
// a pulled file lists the fleet's sessions and `--session` on it sees them.
void assign_pulled_session(MapInfo& info, PulledSubmap& submap);

struct PullReport {
  std::size_t submaps = 0;
  uint64_t rows = 0;           // payload rows read and checked
  uint64_t payload_bytes = 0;  // their bytes
  std::vector<std::string> sessions;  // the sessions that had submaps in the region, by name
  double seconds = 0;
};

// The map every pull builds on: the fleet's parameters and embedding space.
struct FleetDefinition {
  MapParams params;
  MapInfo info;
};

}  // namespace slamvdb::fleet
