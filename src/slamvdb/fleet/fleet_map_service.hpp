#pragma once
// `slamvdb serve --db URL` (issue 24): the fleet map served over HTTP the way `query --db` and
// `classify --db` ask it, every answer read from the database per request, never the whole fleet
// in memory (docs/fleet-design.md, "Serving a fleet"):
// - POST /api/query needs a region: pull_for_search (PostGIS selects the region's submaps, their
//   summaries prune, the rest are scored), the answer of `query --db` on that region; without a
//   region the question is refused (400 naming `region`), never the fleet loaded by accident;
// - GET /api/classes: classify_fleet_region (tile by tile), the rows of `classify --db`;
// - POST /api/at, GET /api/points and /api/nav-grid: the submaps of the request's region (for
//   /api/at the box of its points) pulled into a map of their own for that request, at most
//   `max_region_submaps` of them (more: 413 naming the region);
// - GET /api/info and /api/submaps: the catalog (sessions, submaps, anchors, counts; no payload).
// A request takes a connection of its own (libpq connections are not for several threads at once)
// from a few kept idle between requests (connecting cost about 80 ms here, more than a small
// question). Failures are told apart by their type (fleet_database.hpp): the database's own
// (FleetDatabaseError: unreachable, connection lost, a statement failed) answer 503 naming it,
// damaged or foreign data in it (FleetDataError) 500 with the reason, a question that does not fit
// the fleet its route's 400; never a crash.
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "slamvdb/server/map_service.hpp"

namespace slamvdb::fleet {

class FleetDatabase;

struct FleetServiceOptions {
  std::vector<std::string> sessions{};  // empty: every session
  // Routes that pull their region into memory (at, points, nav-grid): the most submaps one request
  // may pull; a region with more is refused (413) before any payload is read.
  std::size_t max_region_submaps = 64;
  double classify_tile_side = 100.0;  // FleetClassifyOptions::tile_side of GET /api/classes
};

class FleetMapService final : public MapService {
 public:
  // Checks the database before anything listens: reachable, the fleet schema of this slamvdb, a
  // fleet pushed into it (Error naming the redacted URL and what is wrong).
  explicit FleetMapService(std::string url, FleetServiceOptions options = {});
  ~FleetMapService() override;

  std::string source_kind() const override { return "fleet"; }
  QuerySpace space() const override { return space_; }
  // The semantic voxels of every submap in the catalog: an upper bound of the fleet's semantic
  // cells (a cell several submaps share counts once each). Current within kCountMaxAge (a push
  // meanwhile shows): one catalog sum at most every kCountMaxAge, asked by one caller at a time
  // while the others take the last count; a database that cannot answer leaves the last count
  // (GET /healthz and /metrics never fail for it).
  std::size_t semantic_cells() const override;
  nlohmann::json info() const override;
  SearchAnswer search(std::span<const float> query, const SearchOptions& options, bool exact) const override;
  SearchAnswer search_and_classify(std::span<const float> query, const SearchOptions& options, bool exact,
                                   const QuerySet* queries, const ClassifyOptions& classify_options,
                                   ModelIdCheck model_check) const override;
  // Results without the map they came from cannot be classified: answers 501 (the routes classify
  // through search_and_classify).
  void classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                ModelIdCheck model_check) const override;
  std::vector<PointQuery> at(std::span<const Vec3d> points_world, const QuerySet* queries,
                             const ClassifyOptions& options, ModelIdCheck model_check,
                             bool with_embeddings) const override;
  std::vector<ClassifiedCell> classes(const QuerySet& queries, const QueryRegion& region,
                                      const ClassifyOptions& options, ModelIdCheck model_check) const override;
  // The semantic voxels of the region's submaps in the catalog: an upper bound of its cells, so
  // the --max-cells refusal costs a catalog look-up, not a classification.
  std::size_t region_cells(const QueryRegion& region) const override;
  RegionGrid nav_grid(const QuerySet& queries, const NavGridOptions& options, const ClassifyOptions& classify,
                      ModelIdCheck model_check) const override;
  double grid_resolution() const override { return index_cell_; }
  PointChunks points(const PointsRequest& request, const PointValueSource& values) const override;

 private:
  // Runs f(a connection of its own: an idle one, or new) and turns the fleet's failures into
  // RequestErrors: FleetDatabaseError 503, FleetDataError 500 with its reason; other Errors (about
  // the question) pass to the route. A question that failed on an idle connection with a
  // FleetDatabaseError (the database restarted meanwhile) is asked once more on a new one.
  template <class F>
  auto with_database(F&& f) const;
  // The submaps meeting `box` pulled into a map (at most max_region_submaps; more: 413 naming `field`).
  std::shared_ptr<const SemanticMap> pull_region(FleetDatabase& db, const Eigen::AlignedBox3d& box,
                                                 const std::string& field) const;

  std::string url_;
  FleetServiceOptions options_;
  QuerySpace space_;
  double index_cell_ = 0;
  static constexpr std::chrono::milliseconds kCountMaxAge{1000};
  mutable std::atomic<std::size_t> semantic_voxels_{0};
  mutable std::mutex count_mutex_;
  mutable std::chrono::steady_clock::time_point counted_at_{};  // under count_mutex_
  static constexpr std::size_t kMaxIdleConnections = 8;
  mutable std::mutex idle_mutex_;
  mutable std::vector<std::unique_ptr<FleetDatabase>> idle_;  // connections between requests
};

}  // namespace slamvdb::fleet
