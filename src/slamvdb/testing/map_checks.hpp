#pragma once
// For tests only: whether a map holds only finite values. The map model is being rewritten; this
// is the one place that walks its internals for that check, so it is the one place to adapt.
#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::testing {

// "" if every submap pose, every occupied voxel's log-odds and every semantic embedding is finite;
// otherwise a description of the first value that is not.
inline std::string first_non_finite_value(const SemanticMap& map) {
  for (const Submap& submap : map.submaps) {
    if (!submap.T_world_submap.matrix().allFinite()) return fmt::format("submap {}: non-finite pose", submap.id);
    std::string found;
    submap.map.occupancy().for_each_occupied([&](const VoxelKey& key, float log_odds) {
      if (found.empty() && !std::isfinite(log_odds))
        found = fmt::format("submap {}: voxel ({}, {}, {}) has log-odds {}", submap.id, key.x(), key.y(), key.z(),
                            log_odds);
    });
    const SemanticLayer& semantics = submap.map.semantics();
    std::vector<float> embedding(static_cast<std::size_t>(semantics.dim()));
    semantics.for_each([&](const VoxelKey& key, SemanticLayer::Slot slot) {
      if (!found.empty()) return;
      semantics.read(slot, embedding.data());
      for (float v : embedding)
        if (!std::isfinite(v)) {
          found = fmt::format("submap {}: voxel ({}, {}, {}) has a non-finite embedding value", submap.id, key.x(),
                              key.y(), key.z());
          return;
        }
    });
    if (!found.empty()) return found;
  }
  return "";
}

}  // namespace slamvdb::testing
