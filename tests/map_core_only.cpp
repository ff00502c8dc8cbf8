// A program that uses only the map core and the map file (slamvdb::map, slamvdb::store), as
// another C++ project would: it builds a one-submap map, saves it, loads it and reads it through
// the global index. CTest also checks that it links neither libtorch nor OpenCV nor ICU.
#include <cstdio>
#include <filesystem>
#include <unistd.h>

#include "slamvdb/store/map_store.hpp"

int main() {
  using namespace slamvdb;
  MapParams params;
  params.semantic.dim = 4;
  SemanticMap map(params);
  map.integrate_scan(0.0, {Vec3f(3.1f, 0.1f, 0.1f)}, Pose::Identity());
  map.update_active(0.0, [](VoxelMap& v, const Pose&, std::span<const PlacedVoxelMap>) {
    const float e[4] = {1, 0, 0, 0};
    v.occupancy().for_each_occupied([&](const VoxelKey& k, float) { v.semantics().integrate(k, e); });
  });
  map.finish_active_submap();
  const auto path = std::filesystem::temp_directory_path() / ("slamvdb_core_only_" + std::to_string(getpid()) + ".svdb");
  save_map(path, map);
  const SemanticMap loaded = load_map(path);
  std::filesystem::remove(path);
  std::size_t cells = 0;
  loaded.read_index([&](const GlobalIndex& index) { cells = index.size(); });
  std::printf("%zu semantic cells\n", cells);
  return cells == 1 ? 0 : 1;
}
