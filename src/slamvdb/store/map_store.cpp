#include "slamvdb/store/map_store.hpp"

#include <fmt/format.h>

#include <charconv>
#include <memory>
#include <optional>

#include <tbb/parallel_for.h>

#include "slamvdb/core/output_file.hpp"
#include "slamvdb/store/map_rows.hpp"

namespace slamvdb {
namespace fs = std::filesystem;
namespace {

using namespace store;

// Returns what it wrote (without file_bytes), summarised as it goes: nothing is read back (a map
// whose content load_map would refuse is still saved, and refused when loaded).
// `implicit_name`: the session's name when the map lists none (the map file's stem).
MapFileSummary write_database(const fs::path& file, const SemanticMap& map, const std::string& implicit_name) {
  Database db(file, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX);
  // No journal and no syncs: the file is private until the rename, and fsynced before it.
  db.exec(fmt::format(
      "PRAGMA page_size = {}; PRAGMA journal_mode = OFF; PRAGMA synchronous = OFF; PRAGMA locking_mode = EXCLUSIVE;"
      "PRAGMA application_id = {}; PRAGMA user_version = {};",
      kPageSize, kMapApplicationId, kMapFormatVersion));
  db.exec("BEGIN");
  db.exec(kSchema);
  PayloadBytes payload;
  MapFileSummary summary;
  summary.format_version = kMapFormatVersion;
  summary.params = map.params();
  summary.info = map.info();
  const EmbeddingPrecision precision = map.params().semantic.precision;
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& s) {
      const SubmapSummary& row = summary.submaps.emplace_back(summarize(s));
      summary.known_voxels += row.known_voxels;
      summary.occupied_voxels += row.occupied_voxels;
      summary.semantic_voxels += row.semantic_voxels;
      write_submap_row(db, row);
      const PayloadBytes p = write_submap_voxels(db, s, precision);
      payload.occupancy += p.occupancy, payload.semantics += p.semantics;
    });
  summary.info.sessions = sessions_to_write(map.info(), summary.submaps, implicit_name);
  write_session_rows(db, summary.info.sessions);
  db.exec(kIndexes);
  Meta meta = map_meta(map.params(), map.info());
  meta["memory_bytes"] = std::to_string(map.memory_bytes());
  meta["occupancy_payload_bytes"] = std::to_string(payload.occupancy);
  meta["semantic_payload_bytes"] = std::to_string(payload.semantics);
  write_meta(db, meta);
  db.exec("COMMIT");
  db.close();
  summary.memory_bytes = map.memory_bytes();
  summary.occupancy_payload_bytes = payload.occupancy;
  summary.semantic_payload_bytes = payload.semantics;
  return summary;
}

std::unique_ptr<Database> open_reader(const fs::path& path) {
  auto db = std::make_unique<Database>(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX);
  // A map file being written (MapFileWriter) is locked while a submap is committed: wait for it.
  sqlite3_busy_timeout(db->handle(), 10000);
  // Memory-mapped reads: blobs are read where the page cache holds them instead of being copied
  // through SQLite's own cache first.
  db->exec("PRAGMA mmap_size = 1099511627776");
  return db;
}

// A map file whose writer (MapFileWriter) was killed inside a transaction has a hot journal beside
// it. SQLite rolls that back on the first read through a connection that may write; a read-only
// connection may not, so one is opened for that first.
void recover_interrupted_write(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(fs::path(path.string() + "-journal"), ec)) return;
  try {
    Database db(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX);
    sqlite3_busy_timeout(db.handle(), 10000);
    db.exec("SELECT count(*) FROM sqlite_master");
    db.close();
  } catch (const Error& e) {
    throw Error(fmt::format("its last write was interrupted and rolling it back (from {}-journal) needs write "
                            "access: {}", path.filename().string(), e.what()));
  }
}

std::unique_ptr<Database> open_map(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) throw Error("no such file");
  if (!fs::is_regular_file(status)) throw Error("not a regular file");
  recover_interrupted_write(path);
  auto db = open_reader(path);
  const int64_t application_id = pragma_value(*db, "application_id");  // a foreign file fails here
  if (application_id != kMapApplicationId)
    throw Error(fmt::format("not a slamvdb map (SQLite application_id {:#x}, expected {:#x})", application_id,
                            kMapApplicationId));
  const int64_t version = pragma_value(*db, "user_version");
  if (version > kMapFormatVersion)
    throw Error(fmt::format("map format version {} is newer than this slamvdb supports ({}); upgrade slamvdb",
                            version, kMapFormatVersion));
  if (version < 1) throw Error(fmt::format("invalid map format version {}", version));
  return db;
}

uint64_t optional_number(const Meta& meta, const std::string& key) {
  const auto it = meta.find(key);
  if (it == meta.end()) return 0;
  uint64_t v = 0;
  std::from_chars(it->second.data(), it->second.data() + it->second.size(), v);
  return v;
}

MapFileSummary read_summary(const fs::path& path, Database& db) {
  MapFileSummary summary;
  summary.format_version = static_cast<int>(pragma_value(db, "user_version"));
  const Meta meta = read_meta(db);
  summary.params = parse_params(meta);
  summary.info = parse_info(meta, summary.params.semantic.dim);
  summary.memory_bytes = optional_number(meta, "memory_bytes");
  summary.occupancy_payload_bytes = optional_number(meta, "occupancy_payload_bytes");
  summary.semantic_payload_bytes = optional_number(meta, "semantic_payload_bytes");
  summary.submaps = read_submap_rows(db, summary.format_version);
  summary.info.sessions =
      read_session_rows(db, summary.format_version, summary.submaps, path.stem().string(), summary.info.source);
  for (const SubmapSummary& s : summary.submaps) {
    summary.known_voxels += s.known_voxels;
    summary.occupied_voxels += s.occupied_voxels;
    summary.semantic_voxels += s.semantic_voxels;
  }
  summary.file_bytes = fs::file_size(path);
  return summary;
}

template <class F>
auto with_path_context(const char* action, const fs::path& path, F&& f) {
  try {
    return f();
  } catch (const Error& e) {
    throw Error(fmt::format("cannot {} {}: {}", action, path.string(), e.what()));
  } catch (const std::exception& e) {  // filesystem and allocation failures
    throw Error(fmt::format("cannot {} {}: {}", action, path.string(), e.what()));
  }
}

}  // namespace

MapFileSummary save_map(const fs::path& path, const SemanticMap& map) {
  return with_path_context("save map", path, [&] {
    OutputFile out(path);
    if (!out.is_stream()) remove_stale_map_temp_files(out.destination().resolved);
    MapFileSummary summary = write_database(out.temp_path(), map, path.stem().string());
    summary.file_bytes = fs::file_size(out.temp_path());
    out.commit();
    return summary;
  });
}

void remove_stale_map_temp_files(const fs::path& map_file) {
  try {
    remove_stale_temp_files(map_file.parent_path().empty() ? fs::path(".") : map_file.parent_path(),
                            map_file.filename().string());
  } catch (const Error&) {
    // Best effort: the directory is written next anyway, and that reports a real problem.
  }
}

MapFileSummary read_map_summary(const fs::path& path) {
  return with_path_context("read map", path, [&] {
    const auto db = open_map(path);
    return read_summary(path, *db);
  });
}

SemanticMap load_map(const fs::path& path) {
  return with_path_context("load map", path, [&] {
    const auto db = open_map(path);
    const MapFileSummary summary = read_summary(path, *db);
    check_no_orphan_rows(*db);
    // Every submap's occupancy and semantics are independent: read them in parallel, each task
    // with its own read-only connection (about 1.8x faster on two cores).
    const std::size_t n = summary.submaps.size();
    std::vector<std::optional<OccupancyGrid>> grids(n);
    std::vector<std::optional<SemanticLayer>> layers(n);
    tbb::parallel_for(std::size_t{0}, 2 * n, [&](std::size_t task) {
      const SubmapSummary& s = summary.submaps[task / 2];
      const auto reader = open_reader(path);
      if (task % 2 == 0) grids[task / 2].emplace(read_submap_occupancy(*reader, summary.format_version, s, summary.params));
      else layers[task / 2].emplace(read_submap_semantics(*reader, summary.format_version, s, summary.params));
    });
    SemanticMap map(summary.params, summary.info);
    for (std::size_t i = 0; i < n; ++i) check_entry_sessions(*layers[i], summary.submaps[i].info.id, summary.info.sessions);
    for (std::size_t i = 0; i < n; ++i)
      map.add_finished_submap(summary.submaps[i].info,
                              VoxelMap(summary.params, std::move(*grids[i]), std::move(*layers[i])));
    return map;
  });
}

}  // namespace slamvdb
