#include "slamvdb/sessions/session_submaps.hpp"

#include <algorithm>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::sessions {

std::vector<SessionSubmap> session_submaps(const SemanticMap& map) {
  std::vector<SessionSubmap> out;
  for (const SubmapInfo& info : map.submaps()) {
    SessionSubmap submap;
    submap.id = info.id;
    submap.T_world_submap = info.T_world_submap;
    map.read_submap(info.id, [&](const Submap& s) {
      const OccupancyGrid& grid = s.voxels().occupancy();
      std::vector<VoxelKey> keys;
      grid.for_each_occupied([&](const VoxelKey& k, float) { keys.push_back(k); });
      std::sort(keys.begin(), keys.end());
      submap.occupied_submap.reserve(keys.size());
      for (const VoxelKey& k : keys) submap.occupied_submap.push_back(grid.center_of(k).cast<float>());
    });
    out.push_back(std::move(submap));
  }
  return out;
}

}  // namespace slamvdb::sessions
