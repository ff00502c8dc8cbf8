#pragma once
// What `slamvdb info --json` says about a map file, as a library function: the CLI prints it and
// `slamvdb serve` answers GET /api/info with it, so the two say the same.
#include <nlohmann/json.hpp>
#include <map>
#include <optional>
#include <string>

#include "slamvdb/store/map_store.hpp"

namespace slamvdb {

// What only a full load can tell (info --check): the map read through the global index.
struct MapWorldFigures {
  std::size_t index_cells = 0, index_cells_shared = 0, occupied_world_cells = 0;
};

MapWorldFigures map_world_figures(const SemanticMap& map);

// The file's summary (read_map_summary) as JSON, with the world figures under "check" when given.
nlohmann::json map_info_json(const std::string& path, const MapFileSummary& summary,
                             const std::optional<MapWorldFigures>& world);

// The number of submaps of each session (by session id; every listed session, 0 when it has none).
std::map<int, std::size_t> submaps_per_session(const MapFileSummary& summary);

// Bytes per voxel (0 without voxels), as info prints and writes it.
double bytes_per_voxel(uint64_t bytes, std::size_t voxels);

// Roll, pitch, yaw (ZYX convention) in degrees, -0 printed as 0.
Eigen::Vector3d rpy_degrees(const Pose& T);

}  // namespace slamvdb
