#pragma once
// What a push to the fleet map takes and reports (FleetDatabase::push_map).
#include <cstdint>
#include <functional>
#include <string>

#include "slamvdb/core/types.hpp"

namespace slamvdb::fleet {

struct PushOptions {
  std::string session{};  // the session's unique name in the fleet (a drive, a robot's day)
  std::string robot{};    // which robot drove it (free text)
  // Where the session's world frame lies in the fleet frame (from the multi-session alignment
  // or a prior); identity for the session that defines the fleet frame.
  Pose T_fleet_session = Pose::Identity();
  // Called after each submap's transaction (submaps done, submaps in the map), e.g. for a bar.
  std::function<void(std::size_t done, std::size_t total)> on_submap{};
};

struct PushReport {
  int64_t session_id = 0;
  bool session_created = false;
  int submaps_added = 0;      // new in the fleet
  int submaps_unchanged = 0;  // already there with the same payload and anchor: nothing written
  int anchors_moved = 0;      // same payload, new anchor or session frame (or a summary a version-1
                              // row lacked): the catalog row only
  int payloads_replaced = 0;  // the submap changed since its last push (e.g. mapped further)
  uint64_t rows_written = 0;  // payload rows inserted
  uint64_t payload_bytes = 0; // their bytes
  double seconds = 0;
};

}  // namespace slamvdb::fleet
