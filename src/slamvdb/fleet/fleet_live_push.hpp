#pragma once
// `map|slam --push URL`: the fleet gets each submap as the mapper finishes it, through the mapper's
// checkpoint path (the SubmapStore the map file grows by). The map file is written first, the
// fleet second, so a push failure never loses the map: the first failure is kept, nothing more is
// pushed, mapping goes on, and the command reports it at the end (exit 1) with the map file
// complete, from which `slamvdb push` completes the fleet (pushes are idempotent).
#include <memory>
#include <string>

#include "slamvdb/fleet/fleet_push.hpp"
#include "slamvdb/map/submap_store.hpp"

namespace slamvdb::fleet {

class FleetPushingStore final : public SubmapStore {
 public:
  // Connects, creates the schema if there is none, refuses a map the fleet cannot take and creates
  // the session row: all before mapping starts (Error naming the redacted URL and the reason).
  FleetPushingStore(const std::string& url, const MapParams& params, const MapInfo& info, const PushOptions& options);
  ~FleetPushingStore() override;

  // The map file every call goes to first (must outlive this store; set before mapping).
  void keep_in(SubmapStore& file) { file_ = &file; }
  // The submaps of a map a run resumes: a kill between the file's commit and the fleet's leaves
  // the last one missing from the fleet; the others are found unchanged and not written again.
  void push_existing(const SemanticMap& map);

  void save_finished(const SemanticMap& map, int id) override;
  void save_poses(const std::map<int, Pose>& T_world_submap) override;  // anchor updates only
  void save_merge(const SemanticMap& map, int target, int source) override;
  std::pair<SubmapInfo, VoxelMap> load(int id) override;

  // At the end of the run: the session's final source text (Error after a push failure).
  void set_source(const std::string& source);
  // The first push failure, empty when there was none; after it nothing more was pushed.
  const std::string& error() const { return error_; }
  const PushReport& report() const;
  const std::string& display_url() const;

 private:
  template <class F>
  void guarded(F&& push);
  SubmapStore& file();

  std::unique_ptr<FleetDatabase> fleet_;
  std::unique_ptr<FleetPushSession> session_;
  SubmapStore* file_ = nullptr;
  std::string error_;
};

}  // namespace slamvdb::fleet
