#include "slamvdb/sessions/session_selection.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"

namespace slamvdb::sessions {

std::set<int> session_ids_named(const MapInfo& info, const std::vector<std::string>& names) {
  std::set<int> ids;
  for (const std::string& name : names) {
    bool found = false;
    for (const SessionInfo& s : info.sessions)
      if (s.name == name) ids.insert(s.id), found = true;
    if (found) continue;
    std::vector<std::string> known;
    for (const SessionInfo& s : info.sessions) known.push_back(fmt::format("'{}'", escape_control(s.name)));
    throw Error(known.empty() ? fmt::format("no session '{}': the map lists no sessions", escape_control(name))
                              : fmt::format("no session '{}' in the map; its sessions are {}", escape_control(name),
                                            fmt::join(known, ", ")));
  }
  return ids;
}

SessionSelection keep_sessions(SemanticMap& map, const std::vector<std::string>& names) {
  const std::set<int> ids = session_ids_named(map.info(), names);
  const std::optional<int> active = map.active_submap_id();
  SessionSelection out;
  for (const SubmapInfo& s : map.submaps()) {
    if (ids.contains(s.session) || s.id == active) {
      ++out.submaps_kept;
      continue;
    }
    map.remove_finished_submap(s.id);
    ++out.submaps_removed;
  }
  return out;
}

LastObservedSelection keep_last_observed(SemanticMap& map, const std::vector<std::string>& names) {
  const std::set<int> ids = session_ids_named(map.info(), names);
  const std::optional<int> active = map.active_submap_id();
  LastObservedSelection out;
  for (const SubmapInfo& s : map.submaps()) {
    if (s.id == active) continue;
    auto [info, voxels] = map.remove_finished_submap(s.id);
    SemanticLayer& layer = voxels.semantics();
    std::vector<VoxelKey> others;
    layer.for_each([&](SemanticLayer::Handle h) {
      if (!ids.contains(layer.session_of(h))) others.push_back(layer.key_of(h));
    });
    for (const VoxelKey& k : others) layer.erase(k);
    out.semantic_voxels_removed += others.size();
    out.semantic_voxels_kept += layer.size();
    map.add_finished_submap(info, std::move(voxels));
  }
  return out;
}

}  // namespace slamvdb::sessions
