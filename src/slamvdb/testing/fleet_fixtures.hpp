#pragma once
// For the fleet tests: small SIMULATED maps whose submaps lie where a region test expects them.
#include <string>
#include <utility>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::testing {

// SIMULATED ground patches: `submaps` submaps anchored 100 m apart along x, each a flat square of
// `side` x `side` voxels (0.25 m) at z = 0 whose every other voxel has a 4-d embedding.
inline SemanticMap patch_map(int submaps, int side, const std::string& model_id = "fleet-test-space", double voxel = 0.25) {
  MapParams params;
  params.occupancy.voxel_size = voxel;
  params.semantic.dim = 4;
  params.submap_length = 0;
  SemanticMap map(params, {.model_id = model_id, .source = "SIMULATED fleet test patches"});
  for (int id = 0; id < submaps; ++id) {
    VoxelMap voxels(params);
    for (int x = 0; x < side; ++x)
      for (int y = 0; y < side; ++y) {
        voxels.occupancy().set_log_odds({x, y, 0}, 2.0f);
        voxels.occupancy().set_log_odds({x, y, 1}, -1.0f);
        const float e[4] = {static_cast<float>(id), static_cast<float>(x), static_cast<float>(y), 1.0f};
        if ((x + y) % 2 == 0) voxels.semantics().set({x, y, 0}, e, static_cast<uint32_t>(1 + x));
      }
    SubmapInfo info;
    info.id = id;
    info.T_world_submap.translation() = Vec3d(100.0 * id, 0, 0);
    info.time_range = {10.0 * id, 10.0 * id + 9};
    info.path_length = 20;
    map.add_finished_submap(info, std::move(voxels));
  }
  return map;
}

inline std::size_t blocks_of(const SemanticMap& map) {
  std::size_t n = 0;
  for (const SubmapInfo& s : map.submaps())
    map.read_submap(s.id, [&](const Submap& sub) { n += sub.voxels().occupancy().num_blocks(); });
  return n;
}

}  // namespace slamvdb::testing
