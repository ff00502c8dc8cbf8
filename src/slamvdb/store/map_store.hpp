#pragma once
// A SemanticMap is stored as ONE SQLite file (*.svdb): parameters and model info, the submaps
// (anchor pose, time range, path length), their occupancy blocks and their semantic entries, every
// row checked by CRC32 on load, every value checked for meaning (finite, rigid poses, keys inside
// the representable extent, no duplicates, rows of existing submaps). Saving is atomic.
//
// Schema, format version 5 (PRAGMA application_id = kMapApplicationId, user_version = version):
//   meta(key TEXT PRIMARY KEY, value TEXT, crc)                 parameters, info, totals
//   submaps(id PRIMARY KEY, pose BLOB 16 doubles column-major, time_begin, time_end (NULL when
//           empty), path_length, blocks, known_voxels, occupied_voxels, semantic_voxels, crc)
//   occupancy(submap, bx, by, bz, log_odds BLOB, crc)        one row per 8^3 block: 512 floats, zlib
//   semantics(submap, chunk, keys BLOB n x 3 int32, counts BLOB n uint32,
//             embeddings BLOB n x dim fp16|fp32, crc,     up to kSemanticChunkEntries per row
//             stats BLOB n x (weight, spread) float32, stats_crc,   the observation statistics
//             sessions BLOB n uint16 (65535: the submap's own), sessions_crc)   each voxel's
//             last-observing session; both NULL when every entry of the chunk is the submap's own
//   sessions(id PRIMARY KEY, name, source, robot TEXT, time_begin, time_end (NULL when empty), crc)
//   submap_sessions(submap, session, crc, PRIMARY KEY(submap, session))   one row per submap today
//   indexes on occupancy(submap) and semantics(submap, chunk): submaps are read one by one.
//   meta also records the fusion rule ("fusion"), the feature source ("features") and, for the
//   single-view baseline, "semantic_single_view".
// Version 4 (no per-voxel sessions: every voxel was last observed by its submap's session),
// version 3 (no sessions: it loads as one session named after the file, MapInfo::sessions),
// version 2 (no statistics: they load as unknown, "confidence unknown", with weight = count) and
// version 1 (one submap, no time range, no chunk column, no indexes) still load.
// All numbers in blobs are little-endian; a crc covers its row's integer columns and blobs.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

inline constexpr int kMapFormatVersion = 5;
inline constexpr int32_t kMapApplicationId = 0x53564442;  // "SVDB"
inline constexpr std::size_t kSemanticChunkEntries = 4096;

struct SubmapSummary {
  SubmapInfo info;
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
  uint64_t semantic_payload_bytes = 0;    // keys + counts + embeddings + statistics blobs
};

// Writes the map through the one output writer (core/output_file.hpp): to a unique temp file
// beside `path`, fsynced, renamed over `path` (symbolic links followed), directory fsynced; or, for
// a character device or FIFO, to a temp file in the temporary directory copied through to it.
// Returns what the file holds (as written; nothing is read back). Throws Error (naming
// the path and the reason) on failure; a file at `path` is then untouched.
MapFileSummary save_map(const std::filesystem::path& path, const SemanticMap& map);

// Removes the temp files that killed saves of `map_file` left beside it (their process is gone).
// Best effort: never throws.
void remove_stale_map_temp_files(const std::filesystem::path& map_file);

// Throws Error naming the path and the first problem for a missing, foreign, truncated, corrupt
// (CRC mismatch), impossible (non-finite, not rigid, duplicate, out of range) or newer-version file.
SemanticMap load_map(const std::filesystem::path& path);
// The metadata only (checked as far as it goes); load_map checks everything.
MapFileSummary read_map_summary(const std::filesystem::path& path);

}  // namespace slamvdb
