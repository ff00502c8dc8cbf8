#pragma once
// The rows of one submap in a map file, written and read one submap at a time (the streaming
// mapper writes a finished submap while mapping; a viewer may load one region).
#include <cstdint>
#include <map>
#include <string>

#include "slamvdb/store/map_store.hpp"
#include "slamvdb/store/sqlite_db.hpp"
#include "slamvdb/store/submap_payload.hpp"

namespace slamvdb::store {

using Meta = std::map<std::string, std::string, std::less<>>;

// Table definitions of the current format; indexes separately (a whole-map save adds them last).
extern const char* const kSchema;
extern const char* const kIndexes;
// With SQLite's default 4 KiB pages only one 2 KiB occupancy row fits a page and every large blob
// is a long overflow chain: a measured map was 15% larger and saved 1.5x slower than with 64 KiB.
inline constexpr int kPageSize = 65536;

// ---- meta ----
Meta map_meta(const MapParams& params, const MapInfo& info);
MapParams parse_params(const Meta& meta);  // validated; throws Error naming the bad entry
MapInfo parse_info(const Meta& meta, int dim);  // dim: the map's embedding dimension
const std::string& meta_value(const Meta& meta, const std::string& key);
void write_meta(Database& db, const Meta& meta);
Meta read_meta(Database& db);

// ---- submaps ----
SubmapSummary summarize(const Submap& submap);
void write_submap_row(Database& db, const SubmapSummary& summary);
std::vector<SubmapSummary> read_submap_rows(Database& db, int format_version);

// ---- sessions (format version 4; map_sessions.cpp) ----
// The session rows a map is written with: MapInfo::sessions, or one session (id 0, named
// `implicit_name`, the map's source) when it lists none; each session's time range the union of its
// submaps'. Throws Error for a submap of an unlisted session, a duplicate id or an empty name.
std::vector<SessionInfo> sessions_to_write(const MapInfo& info, const std::vector<SubmapSummary>& submaps,
                                           const std::string& implicit_name);
void write_session_rows(Database& db, const std::vector<SessionInfo>& sessions);  // replaces them all
void write_submap_session_row(Database& db, const SubmapInfo& info);              // write_submap_row calls it
// Sets each submap's session from table submap_sessions (version 4); throws Error naming the row
// for a bad CRC, a submap with none or several, or a row of an unknown submap.
void read_submap_session_rows(Database& db, std::vector<SubmapSummary>& submaps);
// Version 4: the sessions table, checked (CRC, names, times, every submap's session listed).
// Versions 1-3: one session, id 0, named `implicit_name`, of `source`, spanning the submaps.
std::vector<SessionInfo> read_session_rows(Database& db, int format_version, const std::vector<SubmapSummary>& submaps,
                                           const std::string& implicit_name, const std::string& source);

// ---- voxels of one submap ----
// Returns the bytes of the written blobs (occupancy compressed, semantics raw).
PayloadBytes write_submap_voxels(Database& db, const Submap& submap, EmbeddingPrecision precision);
// Read and validate one submap's rows (semantics in the file's storage precision). The two halves
// are independent, so a loader may read them on two threads (each with its own connection).
OccupancyGrid read_submap_occupancy(Database& db, int format_version, const SubmapSummary& summary,
                                    const MapParams& params);
SemanticLayer read_submap_semantics(Database& db, int format_version, const SubmapSummary& summary,
                                    const MapParams& params);
// Rows that name a submap the submaps table does not have.
void check_no_orphan_rows(Database& db);
// Throws Error naming the submap and session when an entry of `layer` was last observed in a
// session that `sessions` (the file's) does not list.
void check_entry_sessions(const SemanticLayer& layer, int submap, const std::vector<SessionInfo>& sessions);

}  // namespace slamvdb::store
