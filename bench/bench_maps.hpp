#pragma once
// A large map shared by the map-side benchmarks (index reads, queries, store): built once per run.
#include <memory>
#include <random>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb::bench {

inline constexpr int kSubmaps = 13;
inline constexpr int kEntriesPerSubmap = 100000;  // 1.3 M entries of 512-d fp16 in 1.06 M cells

// Thirteen submaps along a road, each a 100 k-voxel surface patch; neighbours overlap by a fifth,
// so about a fifth of the 1.06 M index cells hold two entries (their count-weighted mean is
// computed on read), as on real drives.
// overlap: the share of a submap its neighbour covers again. dim: of the embeddings (fp16);
// occupancy: also mark each voxel occupied (the viewer's points need it, questions do not).
inline std::unique_ptr<SemanticMap> make_indexed_map(int submaps, double overlap, int dim = 512, bool occupancy = true) {
  MapParams params;
  params.semantic = {dim, EmbeddingPrecision::kFloat16};
  auto map = std::make_unique<SemanticMap>(params);
  uint64_t state = 88172645463325252ULL;  // xorshift: the setup draws 700 M numbers
  auto noise = [&] {
    state ^= state << 13, state ^= state >> 7, state ^= state << 17;
    return static_cast<float>(static_cast<int32_t>(state >> 32)) * (0.05f / 2147483648.0f);
  };
  std::vector<float> e(static_cast<std::size_t>(dim));
  for (int s = 0; s < submaps; ++s) {
    VoxelMap voxels(params);
    const int side = 316;  // 316^2 ~ 100 k
    for (int x = 0; x < side && static_cast<int>(voxels.semantics().size()) < kEntriesPerSubmap; ++x)
      for (int y = 0; y < side && static_cast<int>(voxels.semantics().size()) < kEntriesPerSubmap; ++y) {
        for (float& v : e) v = noise();
        e[static_cast<std::size_t>(s % dim)] += 1.0f;
        if (occupancy) voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
        voxels.semantics().set({x, y, 0}, e.data(), 1 + (x + y) % 50);
      }
    SubmapInfo info;
    info.id = s;
    info.T_world_submap.translation() = Vec3d(s * side * 0.25 * (1.0 - overlap), 0.0, 0.0);
    map->add_finished_submap(info, std::move(voxels));
  }
  return map;
}

inline SemanticMap& indexed_map() {
  static const std::unique_ptr<SemanticMap> map = make_indexed_map(kSubmaps, 0.2);
  return *map;
}

// 1.0 M cells of one entry each (10 submaps side by side): the pure per-voxel cost.
inline SemanticMap& disjoint_map() {
  static const std::unique_ptr<SemanticMap> map = make_indexed_map(10, 0.0);
  return *map;
}

}  // namespace slamvdb::bench
