#pragma once
// Test helpers: a map's semantic cells read through the global index, decoded, keyed by cell.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <tuple>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::testing {

struct DecodedCell {
  uint32_t count = 0;
  uint32_t entries = 0;
  std::vector<float> embedding;
};
using CellTuple = std::tuple<int, int, int>;

// Every occupied voxel of every submap (submap id, voxel x, y, z) with its log-odds.
inline std::map<std::tuple<int, int, int, int>, float> occupied_voxel_log_odds(const SemanticMap& map) {
  std::map<std::tuple<int, int, int, int>, float> out;
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& submap) {
      submap.voxels().occupancy().for_each_occupied([&](const VoxelKey& key, float log_odds) {
        out[{submap.id(), key.x(), key.y(), key.z()}] = log_odds;
      });
    });
  return out;
}

// The same for a map file: two ways of reading the same drive must give the same map.
inline std::map<std::tuple<int, int, int, int>, float> occupied_voxels(const std::filesystem::path& file) {
  return occupied_voxel_log_odds(load_map(file));
}

inline std::map<CellTuple, DecodedCell> index_cells(const SemanticMap& map) {
  std::map<CellTuple, DecodedCell> out;
  map.read_index([&](const GlobalIndex& index) {
    std::vector<float> scratch(static_cast<std::size_t>(index.dim()));
    for (std::size_t i = 0; i < index.size(); ++i) {
      const IndexedVoxel v = index.read(i, scratch.data());
      DecodedCell& c = out[{v.cell.x(), v.cell.y(), v.cell.z()}];
      c.count = v.count;
      c.entries = v.entries;
      c.embedding.resize(scratch.size());
      kernels::decode(v.embedding, c.embedding.data(), scratch.size());
    }
  });
  return out;
}

// Two maps read through their indexes hold the same cells with the same counts and embeddings,
// and the same occupancy totals.
inline void expect_same_index_cells(const SemanticMap& a, const SemanticMap& b) {
  const auto ca = index_cells(a), cb = index_cells(b);
  ASSERT_EQ(ca.size(), cb.size());
  ASSERT_GT(ca.size(), 0u);
  for (auto ia = ca.begin(), ib = cb.begin(); ia != ca.end(); ++ia, ++ib) {
    ASSERT_EQ(ia->first, ib->first);
    ASSERT_EQ(ia->second.count, ib->second.count);
    ASSERT_EQ(ia->second.embedding, ib->second.embedding);
  }
  EXPECT_EQ(a.num_occupied_voxels(), b.num_occupied_voxels());
  EXPECT_EQ(a.num_known_voxels(), b.num_known_voxels());
}

// Bytes the semantic layers of all submaps allocate, per entry.
inline double semantic_bytes_per_entry(const SemanticMap& map) {
  std::size_t bytes = 0, entries = 0;
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& s) {
      bytes += s.voxels().semantics().memory_bytes();
      entries += s.voxels().semantics().size();
    });
  return entries ? static_cast<double>(bytes) / static_cast<double>(entries) : 0.0;
}

}  // namespace slamvdb::testing
