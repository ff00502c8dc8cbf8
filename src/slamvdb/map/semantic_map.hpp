#pragma once
// The whole map: free-floating submaps, each a VoxelMap in its own frame, placed in the world by
// a pose that loop closure may later correct, plus what is needed to interpret the embeddings.
#include <string>
#include <vector>

#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

struct MapInfo {
  std::string model_id;             // the encoder whose embedding space the map is in
  std::string ontology = "rellis3d";
  std::string source;               // what the map was built from (dataset path, simulated or not)
};

struct Submap {
  int id = 0;
  Pose T_world_submap = Pose::Identity();
  VoxelMap map;

  Submap(int id_, const Pose& T, const MapParams& params) : id(id_), T_world_submap(T), map(params) {}
};

struct SemanticMap {
  MapParams params;
  MapInfo info;
  std::vector<Submap> submaps;

  std::size_t num_known_voxels() const {
    std::size_t n = 0;
    for (const auto& s : submaps) n += s.map.occupancy().num_known_voxels();
    return n;
  }
  std::size_t num_occupied_voxels() const {
    std::size_t n = 0;
    for (const auto& s : submaps) n += s.map.occupancy().num_occupied_voxels();
    return n;
  }
  std::size_t num_semantic_voxels() const {
    std::size_t n = 0;
    for (const auto& s : submaps) n += s.map.semantics().size();
    return n;
  }
  std::size_t memory_bytes() const {
    std::size_t n = 0;
    for (const auto& s : submaps) n += s.map.occupancy().memory_bytes() + s.map.semantics().memory_bytes();
    return n;
  }
};

}  // namespace slamvdb
