#pragma once
// Somewhere finished submaps are kept outside memory (a map file: store/map_file_writer.hpp). The
// streaming mapper hands every finished submap to it as soon as the submap is finished, keeps it
// in step with pose corrections and merges, and reads a submap back after letting it leave memory.
// Only the interface lives here: the map itself knows nothing of files.
#include <map>
#include <utility>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

class SubmapStore {
 public:
  virtual ~SubmapStore() = default;
  // Keeps finished submap `id` of `map` (called once per submap, right after it is finished).
  virtual void save_finished(const SemanticMap& map, int id) = 0;
  // Records corrected anchor poses of kept submaps.
  virtual void save_poses(const std::map<int, Pose>& T_world_submap) = 0;
  // `source` was merged into `target` in `map`: the store drops source and keeps target anew.
  virtual void save_merge(const SemanticMap& map, int target, int source) = 0;
  // Reads a kept submap back (its voxels in the map's storage precision).
  virtual std::pair<SubmapInfo, VoxelMap> load(int id) = 0;
};

}  // namespace slamvdb
