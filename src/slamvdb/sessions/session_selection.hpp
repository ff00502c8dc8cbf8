#pragma once
// Restricting a multi-session map to some of its sessions (`--session NAME[,NAME]` on export,
// query and classify): the submaps of the named sessions only. Sessions are chosen by name (what
// `info` lists); a merged submap counts as the session it is in (session_overlap_merge.hpp).
#include <set>
#include <string>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::sessions {

// The ids of the sessions named. Throws Error for a name the map does not list, naming it and
// every known name (so a caller can check this from a file's summary before loading voxels).
std::set<int> session_ids_named(const MapInfo& info, const std::vector<std::string>& names);

struct SessionSelection {
  std::size_t submaps_kept = 0, submaps_removed = 0;
};

// Removes every finished submap of another session than those named (the map's sessions stay
// listed; an active submap, of a map being written, stays). Throws Error as session_ids_named,
// before removing anything.
SessionSelection keep_sessions(SemanticMap& map, const std::vector<std::string>& names);

struct LastObservedSelection {
  std::size_t semantic_voxels_kept = 0, semantic_voxels_removed = 0;
};

// What changed between drives (`export --last-session NAME[,NAME]`): removes the semantic entry
// of every voxel whose last-observing session (SemanticLayer::session_of) is not one of those
// named; the occupancy stays (the other voxels are context). With a later drive named, what is
// left is what that drive saw again or saw first; with an earlier one, what no later drive saw
// again. Finished submaps only. Throws Error as session_ids_named, before changing anything.
LastObservedSelection keep_last_observed(SemanticMap& map, const std::vector<std::string>& names);

}  // namespace slamvdb::sessions
