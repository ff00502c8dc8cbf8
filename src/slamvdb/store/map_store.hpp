#pragma once
// A SemanticMap is stored as ONE SQLite file (*.svdb): parameters and model info, submap poses,
// occupancy blocks (512 log-odds each) and semantic entries in chunks, every row checked by
// CRC32 on load. Saving is atomic: a crash mid-save leaves the previous file intact.
//
// Schema (format version 1; PRAGMA application_id = kMapApplicationId, user_version = version):
//   meta(key TEXT PRIMARY KEY, value TEXT, crc)            parameters, info, totals
//   submaps(id UNIQUE, pose BLOB 16 doubles column-major, blocks, known_voxels,
//           occupied_voxels, semantic_voxels, crc)          in SemanticMap::submaps order
//   occupancy(submap, bx, by, bz, log_odds BLOB, crc)    one row per 8^3 block: 512 floats, zlib
//                                                         (mostly unknown or clamped: ~16x smaller)
//   semantics(submap, keys BLOB n x 3 int32, counts BLOB n uint32,
//             embeddings BLOB n x dim fp16|fp32, crc)        up to kSemanticChunkEntries per row
// All numbers in blobs are little-endian; a crc covers its row's integer columns and blobs.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

inline constexpr int kMapFormatVersion = 1;
inline constexpr int32_t kMapApplicationId = 0x53564442;  // "SVDB"
inline constexpr std::size_t kSemanticChunkEntries = 4096;

struct SubmapSummary {
  int id = 0;
  Pose T_world_submap = Pose::Identity();
  std::size_t blocks = 0;
  std::size_t known_voxels = 0;
  std::size_t occupied_voxels = 0;
  std::size_t semantic_voxels = 0;
};

// What `slamvdb info` shows, read without touching the voxel tables.
struct MapFileSummary {
  int format_version = 0;
  MapParams params;
  MapInfo info;
  std::vector<SubmapSummary> submaps;
  std::size_t known_voxels = 0;
  std::size_t occupied_voxels = 0;
  std::size_t semantic_voxels = 0;
  uint64_t file_bytes = 0;
  uint64_t memory_bytes = 0;              // SemanticMap::memory_bytes() of the saved map
  uint64_t occupancy_payload_bytes = 0;   // compressed log-odds blobs
  uint64_t semantic_payload_bytes = 0;    // keys + counts + embeddings blobs
};

// Writes the map to a unique temp file beside `path`, fsyncs it, renames it over `path` and
// fsyncs the directory. Throws Error (naming the path) on failure; `path` is then untouched.
void save_map(const std::filesystem::path& path, const SemanticMap& map);

// Throws Error naming the path and the reason for a missing, foreign, truncated, corrupt (CRC
// mismatch) or newer-version file.
SemanticMap load_map(const std::filesystem::path& path);
MapFileSummary read_map_summary(const std::filesystem::path& path);

}  // namespace slamvdb
