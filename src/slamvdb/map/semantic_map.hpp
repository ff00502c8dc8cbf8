#pragma once
// The whole map (paper section 6.2.3): free-floating submaps and the global lookup index through
// which every retrieval reads them.
//
// Ownership and threads. The map owns its submaps: one active submap that mapping writes (scans
// and fusion, from one writer thread) and finished submaps that change only by a pose correction
// or a merge. Any number of reader threads may read the index and finished submaps while the
// active one is written: finished submaps and the index are guarded by the map's lock (shared for
// readers), the active submap's voxels by its own lock, which the writer holds only while it
// integrates a scan or fuses an image. Lock order: map, then active submap.
//
// Precision. The active submap accumulates embeddings in fp32, because Eq. 6.1's update
// (x - v) / (n + 1) falls below half an fp16 ulp after about a thousand views and the mean would
// stop moving; a finished submap is stored in params.semantic.precision (fp16 by default).
#include <array>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "slamvdb/map/colour_basis.hpp"
#include "slamvdb/map/global_index.hpp"
#include "slamvdb/map/session_info.hpp"
#include "slamvdb/map/submap.hpp"
#include "slamvdb/map/submap_merge.hpp"

namespace slamvdb {

// The fusion rules a map may record (MapInfo::fusion), in the order of FusionWeighting
// (fusion/projective_fusion.hpp, which converts them): the one list every check uses.
inline constexpr std::array<std::string_view, 3> kFusionRuleNames = {"paper", "quality", "single-view"};

// Every member has a default, so that an aggregate initialiser may name only some of them
// ({.model_id = ..., .source = ...}) without -Wmissing-field-initializers.
struct MapInfo {
  std::string model_id{};             // the encoder whose embedding space the map is in
  std::string ontology = "rellis3d";
  std::string source{};               // what the map was built from (dataset path, simulated or not)
  std::string config{};               // how: the effective options of the command that made it (YAML)
  std::optional<ColourBasis> colour_basis{};  // the colours it is drawn in (see colour_basis.hpp)
  // How views were fused (projective_fusion.hpp: "paper", "quality", "single-view"); maps saved
  // before this was recorded were made with the paper's rule.
  std::string fusion = "paper";
  std::string features{};             // the feature source's settings (the simulated encoder's failure modes)
  // The drives the map was made of (session_info.hpp); empty: one implicit session, id 0.
  std::vector<SessionInfo> sessions{};
};

struct MergeOptions {
  double min_overlap = 0.3;  // occupied_overlap() below this refuses the merge
};

// Throws Error unless T_world_submap is a finite rigid transform inside the representable extent:
// what every submap anchor must be (set_submap_poses checks it; so may a holder of submaps that
// are out of memory).
void check_submap_pose(int id, const Pose& T_world_submap);

class SemanticMap {
 public:
  explicit SemanticMap(const MapParams& params = {}, MapInfo info = {});
  SemanticMap(const SemanticMap&) = delete;
  SemanticMap& operator=(const SemanticMap&) = delete;
  SemanticMap(SemanticMap&& other) noexcept;  // `other` must not be in use by another thread

  const MapParams& params() const { return params_; }
  const MapInfo& info() const { return info_; }
  void set_info(MapInfo info) { info_ = std::move(info); }

  // ---- mapping (one writer thread) ----
  // Integrates a scan into the active submap, first starting a new submap (anchor_for) when there
  // is none or the path since the active one started exceeds params.submap_length.
  ScanIntegrationStats integrate_scan(double stamp, const std::vector<Vec3f>& points_sensor, const Pose& T_world_sensor);
  // Runs f on the active submap's voxels (e.g. to fuse a feature map) under its write lock, with
  // the finished submaps (read-only, e.g. as occluders) held still meanwhile; then brings the
  // index in step. f must not call back into the map. Returns false (f not called) when no submap
  // has been started yet.
  using ActiveUpdate = std::function<void(VoxelMap& voxels, const Pose& T_world_submap,
                                          std::span<const PlacedVoxelMap> finished)>;
  bool update_active(double stamp, const ActiveUpdate& f);
  // Starts a new active submap anchored at T_world_submap (finishing the current one).
  int start_submap(const Pose& T_world_submap);
  // Stores the active submap in its storage precision; it then changes only by pose or merge.
  void finish_active_submap();
  std::optional<int> active_submap_id() const;
  // The anchor a submap started at this sensor pose gets: the world's axes, the voxel corner
  // nearest to the sensor.
  Pose anchor_for(const Pose& T_world_sensor) const;

  // ---- corrections (any thread) ----
  // Sets corrected anchor poses; every index read reflects them at once. Throws Error for an
  // unknown id or a pose that is not a finite rigid transform (nothing is changed then).
  void set_submap_poses(const std::map<int, Pose>& T_world_submap);
  // Merges `source` into `target` when both are finished and overlap by at least
  // options.min_overlap; the source then no longer exists (merged_into(source) says where it
  // went). A refused merge changes nothing.
  MergeReport merge_submaps(int target, int source, const MergeOptions& options = {});

  // ---- building from parts (map loading) ----
  // Adds a finished submap; throws Error if its id exists or its parameters differ from the map's.
  void add_finished_submap(SubmapInfo info, VoxelMap voxels);
  // Lets a finished submap leave memory (and the index); the caller keeps it elsewhere (a
  // SubmapStore) and may add it back with add_finished_submap. Its id is never given out again.
  // Throws Error for an unknown id or the active submap. Returns what left (a caller may add it
  // to another map: merging maps of sessions).
  std::pair<SubmapInfo, VoxelMap> remove_finished_submap(int id);
  // Every finished submap leaves, by id, as remove_finished_submap would have them leave one by
  // one; without an active submap the index is emptied at once instead of entry by entry (merging
  // session maps takes every submap of its inputs: un-binning them one entry at a time was a
  // quarter of a 3 km merge).
  std::vector<std::pair<SubmapInfo, VoxelMap>> take_finished_submaps();

  // ---- reading (any thread) ----
  std::vector<SubmapInfo> submaps() const;   // by id
  std::optional<SubmapInfo> submap_info(int id) const;
  // The submap a merge put submap `id` into, if one did (in this map object's life: not saved);
  // else nullopt. A submap that left the map without a merge left by remove_finished_submap (its
  // holder keeps it elsewhere). Lets a reader that compares the submap list over time (the live
  // server) tell a merge from a submap leaving memory without knowing who holds the map.
  std::optional<int> merged_into(int id) const;
  // f(const Submap&) under the read lock; throws Error for an unknown id.
  void read_submap(int id, const std::function<void(const Submap&)>& f) const;
  // f(const GlobalIndex&) under the read locks (the index and the submaps it refers to).
  void read_index(const std::function<void(const GlobalIndex&)>& f) const;
  // The occupancy of every submap combined on the index grid (submap_merge.hpp), sorted by cell.
  std::vector<WorldOccupancyCell> world_occupancy() const;

  std::size_t num_submaps() const;
  std::size_t num_known_voxels() const;     // summed over submaps (a place in two submaps counts twice)
  std::size_t num_occupied_voxels() const;  // likewise
  std::size_t num_semantic_voxels() const;  // summed semantic entries of all submaps
  std::size_t num_index_cells() const;      // non-empty cells of the global index
  std::size_t memory_bytes() const;         // voxels of every submap plus the index

 private:
  using ReadLock = std::shared_lock<FairSharedMutex>;
  using WriteLock = std::unique_lock<FairSharedMutex>;
  struct ReadGuard;  // the map's read lock, then the active submap's
  uint32_t slot_of(int id) const;  // throws Error for an unknown id
  Submap* active() const { return active_slot_ ? slots_[*active_slot_].get() : nullptr; }
  int start_submap_locked(const Pose& T_world_submap);
  void finish_active_locked();
  void sync_active_locked();  // applies the active layer's change log to the index

  MapParams params_;
  MapInfo info_;
  mutable FairSharedMutex mutex_;                   // slots_, ids_, index_, poses, active_slot_
  std::vector<std::unique_ptr<Submap>> slots_;      // a merged-away submap leaves an empty slot
  std::map<int, uint32_t> ids_;                     // id -> slot
  // merged source id -> target id. At most one entry per id ever given out (a merged id never
  // comes back), 8 bytes each: bounded by the submaps ever made, like ids_ itself.
  std::map<int, int> merged_into_;
  std::optional<uint32_t> active_slot_;
  GlobalIndex index_;
  int next_id_ = 0;
  std::optional<Vec3d> last_scan_position_;         // for the path length of the active submap
};

}  // namespace slamvdb
