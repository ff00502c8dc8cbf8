#include "slamvdb/fleet/fleet_live_push.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_database.hpp"

namespace slamvdb::fleet {

FleetPushingStore::FleetPushingStore(const std::string& url, const MapParams& params, const MapInfo& info,
                                     const PushOptions& options)
    : fleet_(std::make_unique<FleetDatabase>(url)),
      session_(std::make_unique<FleetPushSession>(*fleet_, params, info, options)) {}

FleetPushingStore::~FleetPushingStore() = default;

SubmapStore& FleetPushingStore::file() {
  if (!file_) throw Error("FleetPushingStore: no map file to keep submaps in (keep_in was not called)");
  return *file_;
}

// The push runs only while none has failed. A failure is kept and logged once; it does not stop
// mapping (the file has the submap already, and a robot's map matters more than its upload).
template <class F>
void FleetPushingStore::guarded(F&& push) {
  if (!error_.empty()) return;
  try {
    push();
  } catch (const std::exception& e) {
    error_ = e.what();
    spdlog::error("pushing to the fleet stopped: {} (mapping goes on; the map file keeps every submap)", error_);
  }
}

void FleetPushingStore::push_existing(const SemanticMap& map) {
  for (const SubmapInfo& info : map.submaps())
    guarded([&] { map.read_submap(info.id, [&](const Submap& submap) { session_->push(submap); }); });
}

void FleetPushingStore::save_finished(const SemanticMap& map, int id) {
  file().save_finished(map, id);
  guarded([&] { map.read_submap(id, [&](const Submap& submap) { session_->push(submap); }); });
}

void FleetPushingStore::save_poses(const std::map<int, Pose>& T_world_submap) {
  file().save_poses(T_world_submap);
  guarded([&] { session_->move_anchors(T_world_submap); });
}

void FleetPushingStore::save_merge(const SemanticMap& map, int target, int source) {
  file().save_merge(map, target, source);
  guarded([&] { map.read_submap(target, [&](const Submap& submap) { session_->merge(submap, source); }); });
}

std::pair<SubmapInfo, VoxelMap> FleetPushingStore::load(int id) { return file().load(id); }

void FleetPushingStore::set_source(const std::string& source) {
  guarded([&] { session_->set_source(source); });
}

const PushReport& FleetPushingStore::report() const { return session_->report(); }
const std::string& FleetPushingStore::display_url() const { return fleet_->display_url(); }

}  // namespace slamvdb::fleet
