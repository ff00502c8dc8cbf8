#pragma once
// A map file that grows while mapping goes on (format version 3, map_store.hpp). Each finished
// submap is committed in its own SQLite transaction (rollback journal, full sync), without
// rewriting what the file already holds, so a crash or kill -9 at any moment leaves a file that
// loads and holds every submap committed before it: SQLite rolls an interrupted transaction back
// from its journal the next time the file is opened (load_map and read_map_summary do that).
// Pose corrections rewrite the moved submaps' rows (128-byte poses), a merge the merged submaps.
#include <filesystem>
#include <memory>

#include "slamvdb/map/submap_store.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb {

class OutputFile;
namespace store {
class Database;
}

class MapFileWriter final : public SubmapStore {
 public:
  // Starts a new map file at `path` holding the parameters and info and no submap yet, through the
  // one output writer (core/output_file.hpp): a file already there is replaced atomically (a
  // symbolic link's target, the link stays). A character device or FIFO is written through: the
  // map then grows in a temp file in the temporary directory, copied to it by finish(). Throws
  // Error naming the path.
  static std::unique_ptr<MapFileWriter> create(const std::filesystem::path& path, const MapParams& params,
                                               const MapInfo& info);
  // Continues the map file at `path` (a run to resume): its parameters stay; load it with
  // load_map first. Throws Error naming the path.
  static std::unique_ptr<MapFileWriter> open_existing(const std::filesystem::path& path);
  ~MapFileWriter() override;

  void save_finished(const SemanticMap& map, int id) override;
  void save_poses(const std::map<int, Pose>& T_world_submap) override;
  void save_merge(const SemanticMap& map, int target, int source) override;
  std::pair<SubmapInfo, VoxelMap> load(int id) override;

  // Records the final info (e.g. the colour basis fitted at the end, the effective options) and
  // the totals `slamvdb info` shows; memory_bytes: SemanticMap::memory_bytes() of the whole map
  // (0: not known, e.g. when submaps left memory while mapping). Returns what the file holds; for
  // a device or FIFO, copies the file through to it (the writer is done then).
  MapFileSummary finish(const MapInfo& info, uint64_t memory_bytes);

 private:
  // path: the map file named by the user (for messages); working: the SQLite file written.
  MapFileWriter(const std::filesystem::path& path, const std::filesystem::path& working, MapParams params);
  template <class F>
  void transaction(const char* what, F&& write);
  void erase_submap(int id);

  std::filesystem::path path_, working_;
  MapParams params_;
  std::unique_ptr<OutputFile> stream_output_;  // a device or FIFO, written at finish()
  std::unique_ptr<store::Database> db_;        // declared last: closed before the temp file goes
};

}  // namespace slamvdb
