#include "slamvdb/store/map_file_writer.hpp"

#include <fmt/format.h>

#include "slamvdb/core/output_file.hpp"
#include "slamvdb/store/map_rows.hpp"

namespace slamvdb {
namespace fs = std::filesystem;
using namespace store;

MapFileWriter::MapFileWriter(const fs::path& path, const fs::path& working, MapParams params)
    : path_(path), working_(working), params_(std::move(params)) {
  db_ = std::make_unique<Database>(working_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX);
  // The rollback journal makes every commit atomic; FULL syncs make it durable on power loss too
  // (a commit per submap, so the syncs cost nothing measurable). Other processes may read the file
  // between commits (slamvdb info while mapping).
  db_->exec("PRAGMA journal_mode = DELETE; PRAGMA synchronous = FULL; PRAGMA busy_timeout = 10000;");
}

MapFileWriter::~MapFileWriter() = default;

std::unique_ptr<MapFileWriter> MapFileWriter::create(const fs::path& path, const MapParams& params,
                                                     const MapInfo& info) {
  try {
    auto out = std::make_unique<OutputFile>(path);
    if (!out->is_stream()) remove_stale_map_temp_files(out->destination().resolved);
    {
      Database db(out->temp_path(), SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX);
      db.exec(fmt::format("PRAGMA page_size = {}; PRAGMA journal_mode = OFF; PRAGMA application_id = {}; "
                          "PRAGMA user_version = {};",
                          kPageSize, kMapApplicationId, kMapFormatVersion));
      db.exec("BEGIN");
      db.exec(kSchema);
      db.exec(kIndexes);  // before the rows here: submaps are added one by one and read back by id
      write_meta(db, map_meta(params, info));
      write_session_rows(db, sessions_to_write(info, {}, path.stem().string()));
      db.exec("COMMIT");
      db.close();
    }
    // A file is complete and in place from here on, growing by one commit per submap; a device or
    // FIFO gets the finished file at the end.
    fs::path working = out->temp_path();
    if (!out->is_stream()) {
      working = out->destination().resolved;
      out->commit();
      out.reset();
    }
    auto writer = std::unique_ptr<MapFileWriter>(new MapFileWriter(path, working, params));
    writer->stream_output_ = std::move(out);
    return writer;
  } catch (const std::exception& e) {
    throw Error(fmt::format("cannot start map file {}: {}", path.string(), e.what()));
  }
}

std::unique_ptr<MapFileWriter> MapFileWriter::open_existing(const fs::path& path) {
  const MapFileSummary summary = read_map_summary(path);  // checks it is a map, recovers a killed write
  if (summary.format_version != kMapFormatVersion)
    throw Error(fmt::format("cannot continue map file {}: format version {}, only version {} grows submap by submap",
                            path.string(), summary.format_version, kMapFormatVersion));
  try {
    return std::unique_ptr<MapFileWriter>(new MapFileWriter(path, path, summary.params));
  } catch (const std::exception& e) {
    throw Error(fmt::format("cannot continue map file {}: {}", path.string(), e.what()));
  }
}

template <class F>
void MapFileWriter::transaction(const char* what, F&& write) {
  if (!db_) throw Error(fmt::format("cannot {} in map file {}: it was finished", what, path_.string()));
  try {
    db_->exec("BEGIN IMMEDIATE");
    try {
      write();
      db_->exec("COMMIT");
    } catch (...) {
      sqlite3_exec(db_->handle(), "ROLLBACK", nullptr, nullptr, nullptr);
      throw;
    }
  } catch (const std::exception& e) {
    throw Error(fmt::format("cannot {} in map file {}: {}", what, path_.string(), e.what()));
  }
}

void MapFileWriter::erase_submap(int id) {
  for (const char* sql : {"DELETE FROM submaps WHERE id = ?", "DELETE FROM occupancy WHERE submap = ?",
                          "DELETE FROM semantics WHERE submap = ?", "DELETE FROM submap_sessions WHERE submap = ?"}) {
    Statement erase(*db_, sql);
    erase.bind(1, int64_t{id}).insert();
  }
}

void MapFileWriter::save_finished(const SemanticMap& map, int id) {
  transaction("write a finished submap", [&] {
    erase_submap(id);  // a submap written before (a retried save) is replaced, never doubled
    map.read_submap(id, [&](const Submap& s) {
      write_submap_row(*db_, summarize(s));
      write_submap_voxels(*db_, s, params_.semantic.precision);
    });
  });
}

void MapFileWriter::save_poses(const std::map<int, Pose>& T_world_submap) {
  transaction("record corrected submap poses", [&] {
    for (SubmapSummary& s : read_submap_rows(*db_, kMapFormatVersion)) {
      const auto it = T_world_submap.find(s.info.id);
      if (it == T_world_submap.end()) continue;
      s.info.T_world_submap = it->second;
      Statement erase(*db_, "DELETE FROM submaps WHERE id = ?");
      erase.bind(1, int64_t{s.info.id}).insert();
      write_submap_row(*db_, s);
    }
  });
}

void MapFileWriter::save_merge(const SemanticMap& map, int target, int source) {
  transaction("record a merge of submaps", [&] {
    erase_submap(source);
    erase_submap(target);
    map.read_submap(target, [&](const Submap& s) {
      write_submap_row(*db_, summarize(s));
      write_submap_voxels(*db_, s, params_.semantic.precision);
    });
  });
}

std::pair<SubmapInfo, VoxelMap> MapFileWriter::load(int id) {
  if (!db_) throw Error(fmt::format("cannot read submap {} back from map file {}: it was finished", id, path_.string()));
  try {
    for (const SubmapSummary& s : read_submap_rows(*db_, kMapFormatVersion))
      if (s.info.id == id)
        return {s.info, VoxelMap(params_, read_submap_occupancy(*db_, kMapFormatVersion, s, params_),
                                 read_submap_semantics(*db_, kMapFormatVersion, s, params_))};
    throw Error(fmt::format("it holds no submap {}", id));
  } catch (const std::exception& e) {
    throw Error(fmt::format("cannot read submap {} back from map file {}: {}", id, path_.string(), e.what()));
  }
}

MapFileSummary MapFileWriter::finish(const MapInfo& info, uint64_t memory_bytes) {
  transaction("record the map's info", [&] {
    Meta meta = map_meta(params_, info);
    if (memory_bytes) meta["memory_bytes"] = std::to_string(memory_bytes);
    else db_->exec("DELETE FROM meta WHERE key = 'memory_bytes'");
    Statement sums(*db_,
                   "SELECT (SELECT coalesce(sum(length(log_odds)), 0) FROM occupancy), "
                   // the statistics too, as save_map counts them (the writer writes the current format only)
                   "(SELECT coalesce(sum(length(keys) + length(counts) + length(embeddings) + "
                   "coalesce(length(stats), 0)), 0) FROM semantics)");
    sums.step();
    meta["occupancy_payload_bytes"] = std::to_string(sums.int64(0));
    meta["semantic_payload_bytes"] = std::to_string(sums.int64(1));
    write_meta(*db_, meta);
    // The sessions' time ranges from the submaps written (the info's sessions, or the implicit one).
    write_session_rows(*db_, sessions_to_write(info, read_submap_rows(*db_, kMapFormatVersion), path_.stem().string()));
  });
  MapFileSummary summary = read_map_summary(working_);
  if (stream_output_) {
    db_.reset();
    stream_output_->commit();  // Error: "cannot write PATH: <reason>"
    stream_output_.reset();
  }
  return summary;
}

}  // namespace slamvdb
