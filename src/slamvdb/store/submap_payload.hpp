#pragma once
// One submap's voxel payload as rows, independent of where the rows are kept: the map file
// (SQLite, map_rows.cpp) and the fleet map (PostgreSQL, fleet/) store the same rows with the same
// CRCs, so a row is encoded and checked by one piece of code whichever database holds it.
#include <cstdint>
#include <functional>
#include <optional>
#include <span>

#include "slamvdb/store/map_store.hpp"

namespace slamvdb::store {

// Bytes of the encoded rows (occupancy compressed, semantics raw).
struct PayloadBytes {
  uint64_t occupancy = 0, semantics = 0;
};

// One occupancy block: its key, its log-odds compressed (raw deflate), the CRC over submap id,
// key and blob.
struct OccupancyRow {
  BlockKey key;
  std::span<const std::byte> log_odds;
  int64_t crc = 0;
};
// Up to kSemanticChunkEntries semantic voxels: keys (3 x int32), counts (uint32), embeddings
// (the storage precision), statistics; CRCs over submap id, chunk number and the blobs. From
// format 5, each entry's last-observing session (n uint16, SemanticLayer::kOwnSession for the
// submap's own) when any entry of the chunk names another session, with its CRC; else empty
// (NULL in the database: every entry is the submap's own).
struct SemanticChunkRow {
  int64_t chunk = 0;
  std::span<const std::byte> keys, counts, embeddings, stats;
  int64_t crc = 0, stats_crc = 0;
  std::span<const std::byte> sessions;
  int64_t sessions_crc = 0;  // meaningful when sessions is not empty
};

// Encodes `submap`'s rows in key order (the same map always gives the same rows), handing each to
// the callbacks; the spans are valid during the call only.
PayloadBytes encode_submap_payload(const Submap& submap, EmbeddingPrecision precision,
                                   const std::function<void(const OccupancyRow&)>& occupancy_row,
                                   const std::function<void(const SemanticChunkRow&)>& semantic_row);

// Rebuild a submap's occupancy from its rows in any order, checking each (CRC, extent, size,
// value range, duplicates) and the totals against the submap's summary: a clear Error names the
// row and the reason. `format_version` is the map file format the rows were written in.
class OccupancyRowReader {
 public:
  OccupancyRowReader(int64_t submap_id, int format_version, const MapParams& params);
  ~OccupancyRowReader();
  void add(int64_t bx, int64_t by, int64_t bz, std::span<const std::byte> log_odds, int64_t crc);
  OccupancyGrid finish(const SubmapSummary& summary);

 private:
  struct Codec;
  int64_t id_;
  int version_;
  OccupancyParams params_;
  OccupancyGrid grid_;
  std::unique_ptr<Codec> codec_;
  std::size_t known_ = 0;
};

// Rebuild a submap's semantic layer from its chunks in chunk order (chunk numbers from format 2,
// statistics from format 3: nullopt before), checking each and the total.
class SemanticChunkReader {
 public:
  SemanticChunkReader(int64_t submap_id, int format_version, const MapParams& params);
  // sessions / sessions_crc: nullopt when NULL (or before format 5); one without the other is damage.
  void add(std::optional<int64_t> chunk_number, std::span<const std::byte> keys, std::span<const std::byte> counts,
           std::span<const std::byte> embeddings, int64_t crc, std::span<const std::byte> stats, int64_t stats_crc,
           std::optional<std::span<const std::byte>> sessions = std::nullopt,
           std::optional<int64_t> sessions_crc = std::nullopt);
  SemanticLayer finish(const SubmapSummary& summary);

 private:
  int64_t id_;
  int version_;
  SemanticParams params_;
  SemanticLayer layer_;
  int64_t next_chunk_ = 0;
  std::vector<VoxelKey> keys_;
  std::vector<int32_t> raw_keys_;
  std::vector<uint32_t> counts_;
  std::vector<VoxelStatistics> stats_;
  std::vector<uint16_t> sessions_;
};

}  // namespace slamvdb::store
