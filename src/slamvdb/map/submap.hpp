#pragma once
// A free-floating submap (paper section 6.2.3): its own occupancy and semantic layers in its own
// frame, placed in the world by an anchor pose that a loop closure may later correct. Only the
// SemanticMap that owns it changes it.
#include <algorithm>
#include <limits>

#include "slamvdb/core/fair_shared_mutex.hpp"

#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

struct TimeRange {
  double begin = std::numeric_limits<double>::infinity();
  double end = -std::numeric_limits<double>::infinity();
  bool empty() const { return begin > end; }
  void extend(double t) { begin = std::min(begin, t), end = std::max(end, t); }
  void extend(const TimeRange& r) {
    if (!r.empty()) extend(r.begin), extend(r.end);
  }
};

// What a submap is, without its voxels (listing, files).
struct SubmapInfo {
  int id = 0;
  Pose T_world_submap = Pose::Identity();
  TimeRange time_range;   // stamps of the scans and images integrated into it
  double path_length = 0; // metres driven while it was the active submap
  bool finished = false;
  int session = 0;        // the session it was mapped in (SessionInfo::id, session_info.hpp)
};

class Submap {
 public:
  Submap(const SubmapInfo& info, VoxelMap voxels) : info_(info), voxels_(std::move(voxels)) {}
  Submap(const Submap&) = delete;
  Submap& operator=(const Submap&) = delete;

  int id() const { return info_.id; }
  const SubmapInfo& info() const { return info_; }
  const Pose& T_world_submap() const { return info_.T_world_submap; }
  bool finished() const { return info_.finished; }
  const VoxelMap& voxels() const { return voxels_; }

 private:
  friend class SemanticMap;
  SubmapInfo info_;
  VoxelMap voxels_;
  // Guards voxels_ while the submap is active (the mapping thread writes it); a finished submap
  // changes only under the owning map's exclusive lock (pose corrections, merges).
  mutable FairSharedMutex data_mutex_;
};

}  // namespace slamvdb
