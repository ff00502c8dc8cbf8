#pragma once
// What the server reads a map through. Today a SemanticMap in memory (a saved map loaded once, or
// the map a running `map --serve` builds); `serve --db URL` puts a fleet map read from PostgreSQL per
// request behind the same interface (fleet/fleet_map_service.hpp), so the routes never touch a SemanticMap.
// Every call may come from several request threads at once: implementations are thread-safe.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <nlohmann/json.hpp>
#include <span>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/query/ann_index.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/query/nav_grid.hpp"
#include "slamvdb/query/query_terms.hpp"
#include "slamvdb/server/points_chunks.hpp"

namespace slamvdb {

class MapService {
 public:
  virtual ~MapService() = default;
  // The embedding space questions are asked in (dimension, model id).
  virtual QuerySpace space() const = 0;
  // Cells of the global index that hold an embedding.
  virtual std::size_t semantic_cells() const = 0;
  // What `slamvdb info --json --check` says about the map (GET /api/info).
  virtual nlohmann::json info() const = 0;
  // similarity_search over the map (query/map_query.hpp), the CLI's function: through the
  // service's ANN index when it has one, the question allows it (top_k without threshold or
  // region) and `exact` is false; else every cell is scored. `approximate` says which.
  struct SearchAnswer {
    std::vector<ScoredCell> cells;
    bool approximate = false;
  };
  virtual SearchAnswer search(std::span<const float> query, const SearchOptions& options, bool exact) const = 0;
  // search(), then with `queries` classify() of its cells, over one look at the map: what POST
  // /api/query answers. A fleet map (fleet/fleet_map_service.hpp) reads its region once for both.
  virtual SearchAnswer search_and_classify(std::span<const float> query, const SearchOptions& options, bool exact,
                                           const QuerySet* queries, const ClassifyOptions& classify_options,
                                           ModelIdCheck model_check) const;
  // Where the answers come from, said in the JSON answers of query, classes, info and submaps as
  // "served_from": "file" (a saved map), "live" (a map being built) or "fleet" (a fleet map in
  // PostgreSQL, read per request).
  virtual std::string source_kind() const { return "file"; }
  // query_points over the map (what `query --at` answers), with classes when `queries` is given.
  virtual std::vector<PointQuery> at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                     const ClassifyOptions& options, ModelIdCheck model_check,
                                     bool with_embeddings) const = 0;
  // classify_results over the map, for answers that carry a class (a query set given to the server).
  virtual void classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                        ModelIdCheck model_check) const = 0;
  // classify_region over the map in cell order (what `classify --bbox -o X.csv` writes).
  virtual std::vector<ClassifiedCell> classes(const QuerySet& queries, const QueryRegion& region,
                                              const ClassifyOptions& options, ModelIdCheck model_check) const = 0;
  // How many cells classes() would answer for `region` (count_region_cells): checked against a limit first.
  virtual std::size_t region_cells(const QueryRegion& region) const = 0;
  // The navigation grid of options.region (required) as `classify --bbox ... --grid` builds it
  // (classify_region + build_nav_grid), and the path driven (submap_path) for its picture.
  struct RegionGrid {
    NavGrid grid;
    std::vector<Eigen::Vector2d> path;
  };
  virtual RegionGrid nav_grid(const QuerySet& queries, const NavGridOptions& options, const ClassifyOptions& classify,
                              ModelIdCheck model_check) const = 0;
  // Metres per cell of the map's navigation grid (its index cell).
  virtual double grid_resolution() const = 0;
  // GET /api/points: the occupied voxels as chunks per (submap, octree node), a class or score each
  // (collect_point_chunks, server/points_chunks.hpp).
  virtual PointChunks points(const PointsRequest& request, const PointValueSource& values) const = 0;
  // A counter that grows whenever the map changes (a submap finished, moved or merged): GET
  // /api/events tells viewers. A saved map never changes: 0.
  virtual std::uint64_t changes() const { return 0; }
  // Live mode (live_map_service.hpp): what changed after counter value `after`, oldest first, each
  // {"changes": N, "added": [...], "moved": [...], "grew": [...], "merged": [{"id", "into"}...],
  //  "unloaded": [...], "active": ID|null}
  // (docs/serve-design.md "Live mode"); [] for a map that never changes.
  virtual nlohmann::json changes_since(std::uint64_t /*after*/) const { return nlohmann::json::array(); }
  // Live mode: {"mapping": bool, "scans_done": N, "scans_total": N (0: not known)}; null otherwise.
  virtual nlohmann::json progress() const { return nullptr; }
  // Live mode: a client follows the map (a GET /api/events stream sent its first event), which
  // `map --serve-wait-viewer` waits for. Nothing otherwise.
  virtual void event_stream_opened() const {}
  // The submaps whose voxels the map's answers leave out now, by id, ascending: live mode's
  // submaps out of memory (kept in the map file, not read back for questions). A saved map has
  // them all: none.
  virtual std::vector<int> submaps_out_of_memory() const { return {}; }
  // The ANN index of top-k questions (GET /healthz "index"): "none", "building" (questions are
  // scored exactly meanwhile), "ready" or "failed" (exact, the reason logged).
  virtual std::string index_state() const { return "none"; }
};

// A SemanticMap in memory, read through its global index (SemanticMap's own locks make concurrent
// readers safe, also while a mapper writes to it).
class SemanticMapService final : public MapService {
 public:
  // `ann`: the map's ANN index (null: every search is exact, until build_index_in_background).
  SemanticMapService(std::shared_ptr<const SemanticMap> map, nlohmann::json info, std::unique_ptr<AnnIndex> ann = nullptr);
  ~SemanticMapService() override;  // asks a build still running to stop, and waits for it
  SemanticMapService(const SemanticMapService&) = delete;
  SemanticMapService& operator=(const SemanticMapService&) = delete;
  // Builds the ANN index on a thread of its own with `build` (given a flag that asks it to stop
  // early, by throwing): the service answers at once, every search exact, and switches to the index
  // when it is ready; a build that throws leaves the service exact (state "failed", logged). Once.
  using IndexBuilder = std::function<std::unique_ptr<AnnIndex>(const SemanticMap&, const std::atomic<bool>& stop)>;
  void build_index_in_background(IndexBuilder build);
  // Waits until no build is running (true) or `timeout` has passed (false).
  bool wait_for_index(std::chrono::milliseconds timeout) const;
  std::string index_state() const override;
  QuerySpace space() const override;
  std::size_t semantic_cells() const override;
  nlohmann::json info() const override { return info_; }
  SearchAnswer search(std::span<const float> query, const SearchOptions& options, bool exact) const override;
  std::shared_ptr<const AnnIndex> ann() const;
  void classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                ModelIdCheck model_check) const override;
  std::vector<PointQuery> at(std::span<const Vec3d> points_world, const QuerySet* queries,
                             const ClassifyOptions& options, ModelIdCheck model_check,
                             bool with_embeddings) const override;
  std::vector<ClassifiedCell> classes(const QuerySet& queries, const QueryRegion& region,
                                      const ClassifyOptions& options, ModelIdCheck model_check) const override;
  std::size_t region_cells(const QueryRegion& region) const override;
  RegionGrid nav_grid(const QuerySet& queries, const NavGridOptions& options, const ClassifyOptions& classify,
                      ModelIdCheck model_check) const override;
  double grid_resolution() const override;
  PointChunks points(const PointsRequest& request, const PointValueSource& values) const override;  // points_chunks.cpp

 private:
  std::shared_ptr<const SemanticMap> map_;
  nlohmann::json info_;
  mutable std::mutex ann_mutex_;  // guards ann_ and state_; a search copies the pointer and lets go
  mutable std::condition_variable ann_built_;
  std::shared_ptr<const AnnIndex> ann_;
  std::string state_ = "none";
  std::atomic<bool> stop_build_{false};
  std::thread builder_;
};

// A saved map, loaded once and checked in full; its info is `info --json --check` of the file.
// With `ann`, an ANN index is built over it with those options in the background (its figures are
// logged when it is ready) when it has at least `ann_min_cells` semantic cells.
std::shared_ptr<SemanticMapService> open_map_file_service(const std::filesystem::path& path,
                                                          const AnnOptions* ann = nullptr, std::size_t ann_min_cells = 0);

}  // namespace slamvdb
