#pragma once
// For tests only: whether a map holds only finite values (submap poses, occupancy log-odds,
// semantic embeddings), walking every submap through the map's read API.
#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::testing {

// "" if every submap pose, every occupied voxel's log-odds and every semantic embedding is finite;
// otherwise a description of the first value that is not.
inline std::string first_non_finite_value(const SemanticMap& map) {
  std::string found;
  for (const SubmapInfo& info : map.submaps()) {
    map.read_submap(info.id, [&](const Submap& submap) {
      if (!submap.T_world_submap().matrix().allFinite()) {
        found = fmt::format("submap {}: non-finite pose", submap.id());
        return;
      }
      submap.voxels().occupancy().for_each_occupied([&](const VoxelKey& key, float log_odds) {
        if (found.empty() && !std::isfinite(log_odds))
          found = fmt::format("submap {}: voxel ({}, {}, {}) has log-odds {}", submap.id(), key.x(), key.y(), key.z(),
                              log_odds);
      });
      const SemanticLayer& semantics = submap.voxels().semantics();
      std::vector<float> embedding(static_cast<std::size_t>(semantics.dim()));
      semantics.for_each([&](SemanticLayer::Handle h) {
        if (!found.empty()) return;
        semantics.read(h, embedding.data());
        for (float v : embedding)
          if (!std::isfinite(v)) {
            const VoxelKey& key = semantics.key_of(h);
            found = fmt::format("submap {}: voxel ({}, {}, {}) has a non-finite embedding value", submap.id(), key.x(),
                                key.y(), key.z());
            return;
          }
      });
    });
    if (!found.empty()) return found;
  }
  return "";
}

}  // namespace slamvdb::testing
