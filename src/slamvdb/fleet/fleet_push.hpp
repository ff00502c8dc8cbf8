#pragma once
// What a push to the fleet map takes and reports (FleetDatabase::push_map), and one session's push
// submap by submap (FleetPushSession: `push` of a map file, `map|slam --push` while mapping).
#include <cstdint>
#include <functional>
#include <map>
#include <string>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/semantic_map.hpp"

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
  int payloads_replaced = 0;  // the submap changed since its last push (e.g. mapped further, merged into)
  int submaps_removed = 0;    // merged into another submap while mapping: its rows deleted
  uint64_t rows_written = 0;  // payload rows inserted
  uint64_t payload_bytes = 0; // their bytes
  double seconds = 0;
};

class FleetDatabase;

// One session's push, one transaction per write: FleetDatabase::push_map pushes a map file's
// submaps through it, and `map|slam --push` each submap as the mapper finishes it
// (fleet_live_push.hpp). Idempotent as push_map: a submap already there with the same payload and
// anchor writes nothing, so a crashed run repeated pushes nothing twice.
class FleetPushSession {
 public:
  // Creates the schema if there is none, refuses a map whose embedding space, voxel size, ontology
  // or clamping differ from the fleet's (Error naming the entry, before anything is written),
  // defines the fleet on the first push, and creates (or updates) the session row. `fleet` must
  // outlive the session.
  FleetPushSession(FleetDatabase& fleet, const MapParams& params, const MapInfo& info, const PushOptions& options);
  // One finished submap in one transaction: catalog row and payload rows, the catalog row alone
  // when only its anchor moved, nothing when unchanged. Extends the session's time range.
  void push(const Submap& submap);
  // `target` now holds submap `source` too (a loop showed them to be one place): target's payload is
  // replaced and source's rows deleted, in one transaction (no reader sees source's voxels twice
  // or not at all).
  void merge(const Submap& target, int source);
  // A loop correction: the catalog rows (anchor, footprint, revision) of the submaps this session
  // has pushed, in one transaction; never a payload. Ids not pushed yet (the active submap) are
  // skipped: they go with their final anchor when they finish.
  void move_anchors(const std::map<int, Pose>& T_world_submap);
  // The session's source text, when it is known only at the end (`slam` names its odometry).
  void set_source(const std::string& source);
  const PushReport& report() const { return report_; }
  const std::string& display_url() const;

 private:
  FleetDatabase& fleet_;
  MapParams params_;
  PushOptions options_;
  PushReport report_;
  // The box of each pushed submap's blocks in its own frame: a correction's footprint is made from
  // it without reading the submap back (it may have left memory).
  std::map<int, Eigen::AlignedBox3d> local_bounds_;
};

}  // namespace slamvdb::fleet
