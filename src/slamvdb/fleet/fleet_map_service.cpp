#include "slamvdb/fleet/fleet_map_service.hpp"

#include <fmt/format.h>

#include <optional>

#include "slamvdb/core/deadline.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_classify.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/fleet/fleet_search.hpp"
#include "slamvdb/server/request_decoding.hpp"

namespace slamvdb::fleet {
namespace {

nlohmann::json time_range_json(const std::optional<std::pair<double, double>>& t) {
  return t ? nlohmann::json({t->first, t->second}) : nlohmann::json();
}

nlohmann::json pose_rows(const Pose& T) {
  nlohmann::json rows = nlohmann::json::array();
  const Eigen::Matrix4d m = T.matrix();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

nlohmann::json box_json(const Eigen::AlignedBox3d& b) {
  return {b.min().x(), b.min().y(), b.min().z(), b.max().x(), b.max().y(), b.max().z()};
}

}  // namespace

FleetMapService::FleetMapService(std::string url, FleetServiceOptions options)
    : url_(std::move(url)), options_(std::move(options)) {
  FleetDatabase db(url_);  // Error "cannot connect to the fleet database URL: reason"
  const int version = db.schema_version();
  if (version == 0)
    throw Error(fmt::format("fleet database {} holds no fleet map (no slamvdb schema): push a map into it first "
                            "(slamvdb push MAP.svdb --db URL)",
                            db.display_url()));
  if (version != kFleetSchemaVersion)
    throw Error(fmt::format("fleet database {} has schema version {}, this slamvdb reads version {} ({})",
                            db.display_url(), version, kFleetSchemaVersion,
                            version < kFleetSchemaVersion ? "a push with this slamvdb migrates it; serve writes nothing"
                                                          : "use a newer slamvdb"));
  const FleetDefinition definition = db.definition();
  space_ = {definition.params.semantic.dim, definition.info.model_id};
  index_cell_ = definition.params.index_cell();
  semantic_voxels_ = db.semantic_voxels();
  counted_at_ = std::chrono::steady_clock::now();
}

FleetMapService::~FleetMapService() = default;

template <class F>
auto FleetMapService::with_database(F&& f) const {
  const auto give_back = [this](std::unique_ptr<FleetDatabase> db) {
    const std::lock_guard lock(idle_mutex_);
    if (idle_.size() < kMaxIdleConnections) idle_.push_back(std::move(db));
  };
  for (bool retried = false;; retried = true) {
    std::unique_ptr<FleetDatabase> db;
    {
      const std::lock_guard lock(idle_mutex_);
      if (!idle_.empty()) db = std::move(idle_.back()), idle_.pop_back();
    }
    const bool reused = db != nullptr;
    if (!db) try {
        db = std::make_unique<FleetDatabase>(url_);
      } catch (const FleetDatabaseError& e) {
        throw RequestError(503, "", fmt::format("the fleet database cannot be reached: {}", e.what()));
      }
    try {
      auto answer = f(*db);
      give_back(std::move(db));
      return answer;
    } catch (const RequestError&) {
      give_back(std::move(db));  // about the question (a region too large, ...): the connection is fine
      throw;
    } catch (const DeadlineExceeded&) {
      throw;  // dropped: a statement may have been cut short
    } catch (const FleetDatabaseError& e) {
      // The database failed (gone, restarted, a shard down, a statement cut by a timeout): may
      // answer later, so 503. The connection is dropped (it may be broken).
      if (reused && !retried) {
        // The idle connections may all predate a restart of the database: none is kept, and the
        // question is asked once more on a new one.
        const std::lock_guard lock(idle_mutex_);
        idle_.clear();
        continue;
      }
      throw RequestError(503, "", fmt::format("the fleet database cannot answer: {}", e.what()));
    } catch (const FleetDataError& e) {
      // The database answered with damaged or foreign rows (a payload's checksum, ...): asking again
      // gives the same, so not 503; the reason is said (not a stack trace).
      give_back(std::move(db));
      throw RequestError(500, "", e.what());
    } catch (const Error&) {
      give_back(std::move(db));  // about the question (a query set that does not fit): the route's status
      throw;
    }
  }
}

std::size_t FleetMapService::semantic_cells() const {
  const std::unique_lock lock(count_mutex_, std::try_to_lock);
  if (lock.owns_lock() && std::chrono::steady_clock::now() - counted_at_ >= kCountMaxAge) {
    try {
      semantic_voxels_ = with_database([](FleetDatabase& db) { return db.semantic_voxels(); });
    } catch (const std::exception&) {
      // The last count stays (the routes that ask the database say why it cannot answer).
    }
    counted_at_ = std::chrono::steady_clock::now();
  }
  return semantic_voxels_.load();
}

nlohmann::json FleetMapService::info() const {
  return with_database([&](FleetDatabase& db) {
    const FleetDefinition definition = db.definition();
    const FleetCatalog catalog = db.catalog();
    std::size_t known = 0, occupied = 0, semantic = 0;
    nlohmann::json submaps = nlohmann::json::array();
    for (const CatalogSubmap& m : catalog.submaps) {
      known += m.known_voxels, occupied += m.occupied_voxels, semantic += m.semantic_voxels;
      const Vec3d t = m.T_fleet_submap.translation();
      submaps.push_back({{"id", m.id},
                         {"session", m.session},
                         {"T_world_submap", pose_rows(m.T_fleet_submap)},  // the world is the fleet frame
                         {"translation", {t.x(), t.y(), t.z()}},
                         {"time_range", time_range_json(m.time_range)},
                         {"path_length", m.path_length},
                         {"blocks", m.blocks},
                         {"known_voxels", m.known_voxels},
                         {"occupied_voxels", m.occupied_voxels},
                         {"semantic_voxels", m.semantic_voxels},
                         {"revision", m.revision},
                         {"bounds", box_json(m.bounds_fleet)}});
    }
    semantic_voxels_ = semantic;
    nlohmann::json sessions = nlohmann::json::array();
    for (const CatalogSession& s : catalog.sessions)
      sessions.push_back({{"id", s.id},
                          {"name", s.name},
                          {"source", s.source},
                          {"robot", s.robot},
                          {"time_range", time_range_json(s.time_range)},
                          {"T_fleet_session", pose_rows(s.T_fleet_session)},
                          {"submaps", s.submaps}});
    nlohmann::json shards = nlohmann::json::array();
    for (const auto& [id, name] : db.shards()) shards.push_back({{"id", id}, {"name", name}});
    nlohmann::json answer{{"path", db.display_url()},
                          {"database", db.display_url()},
                          {"schema_version", kFleetSchemaVersion},
                          {"voxels", {{"known", known}, {"occupied", occupied}, {"semantic", semantic}}},
                          {"voxel_size", definition.params.occupancy.voxel_size},
                          {"embedding_dim", definition.params.semantic.dim},
                          {"precision", std::string(to_string(definition.params.semantic.precision))},
                          {"model_id", definition.info.model_id},
                          {"ontology", definition.info.ontology},
                          {"sessions_asked", options_.sessions},
                          {"shards", shards},
                          {"sessions", sessions},
                          {"submaps", submaps}};
    // Submap rows naming no session cannot be placed in the fleet frame: left out, and said.
    if (catalog.submaps_without_session > 0) answer["submaps_without_session"] = catalog.submaps_without_session;
    return answer;
  });
}

MapService::SearchAnswer FleetMapService::search(std::span<const float> query, const SearchOptions& options,
                                                 bool exact) const {
  return search_and_classify(query, options, exact, nullptr, {}, ModelIdCheck::kRequireMatch);
}

MapService::SearchAnswer FleetMapService::search_and_classify(std::span<const float> query,
                                                              const SearchOptions& options, bool /*exact*/,
                                                              const QuerySet* queries,
                                                              const ClassifyOptions& classify_options,
                                                              ModelIdCheck model_check) const {
  if (!options.region)
    throw RequestError(400, "region",
                       "\"region\" (a bbox, or near with radius) is required for a fleet map: this server reads the "
                       "region's submaps from the database per question and never the whole fleet");
  return with_database([&](FleetDatabase& db) {
    // What `query --db` does (apps/map_source_options.hpp): the submaps that can hold the answer,
    // then the search on them, exact (no ANN index over a fleet).
    PrunedRegion pruned = pull_for_search(db, {options.region->bounds(), options_.sessions}, query, options);
    SearchAnswer answer{similarity_search(pruned.map, query, options), false};
    if (queries) classify_results(pruned.map, *queries, answer.cells, classify_options, model_check);
    return answer;
  });
}

void FleetMapService::classify(const QuerySet&, std::span<ScoredCell>, const ClassifyOptions&, ModelIdCheck) const {
  throw RequestError(501, "", "a fleet map classifies the results of a search only (search_and_classify)");
}

std::shared_ptr<const SemanticMap> FleetMapService::pull_region(FleetDatabase& db, const Eigen::AlignedBox3d& box,
                                                                const std::string& field) const {
  const PullRequest request{box, options_.sessions};
  const std::size_t submaps = db.region_catalog(request).size();
  if (submaps > options_.max_region_submaps)
    throw RequestError(413, field,
                       fmt::format("the region meets {} submaps of the fleet; this server reads at most {} into "
                                   "memory for one request (serve --max-region-submaps): ask a smaller region",
                                   submaps, options_.max_region_submaps));
  return std::make_shared<const SemanticMap>(db.pull_map(request));
}

std::vector<PointQuery> FleetMapService::at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                            const ClassifyOptions& options, ModelIdCheck model_check,
                                            bool with_embeddings) const {
  if (points_world.empty()) return {};
  // The box of the points, one index cell wider on every side: every submap with an entry in a
  // point's cell has a voxel in that cell, so its footprint meets the box.
  Eigen::AlignedBox3d box;
  for (const Vec3d& p : points_world) box.extend(p);
  box.min().array() -= index_cell_;
  box.max().array() += index_cell_;
  return with_database([&](FleetDatabase& db) {
    const auto map = pull_region(db, box, "points");
    return query_points(*map, points_world, queries, options, model_check, with_embeddings);
  });
}

std::vector<ClassifiedCell> FleetMapService::classes(const QuerySet& queries, const QueryRegion& region,
                                                     const ClassifyOptions& options, ModelIdCheck model_check) const {
  return with_database([&](FleetDatabase& db) {
    FleetClassifyOptions o{options, model_check, options_.sessions, options_.classify_tile_side};
    return classify_fleet_region(db, region, queries, o).cells;  // sort_by_cell order, as `classify --db`
  });
}

std::size_t FleetMapService::region_cells(const QueryRegion& region) const {
  return with_database([&](FleetDatabase& db) {
    std::size_t cells = 0;
    for (const RegionSubmap& s : db.region_catalog({region.bounds(), options_.sessions})) cells += s.semantic_voxels;
    return cells;
  });
}

MapService::RegionGrid FleetMapService::nav_grid(const QuerySet& queries, const NavGridOptions& options,
                                                 const ClassifyOptions& classify, ModelIdCheck model_check) const {
  if (!options.region) throw RequestError(400, "bbox", "a fleet map's navigation grid needs a region");
  return with_database([&](FleetDatabase& db) {
    const SemanticMapService region(pull_region(db, options.region->bounds(), options.region->box ? "bbox" : "radius"),
                                    nlohmann::json::object());
    return region.nav_grid(queries, options, classify, model_check);
  });
}

PointChunks FleetMapService::points(const PointsRequest& request, const PointValueSource& values) const {
  if (!request.region)
    throw RequestError(400, "bbox", "GET /api/points on a fleet map needs a region (bbox, or near with radius)");
  if (request.submap)
    throw RequestError(400, "submap", "GET /api/points on a fleet map answers regions, not submap ids (ids are per "
                                      "session)");
  return with_database([&](FleetDatabase& db) {
    const SemanticMapService region(pull_region(db, request.region->bounds(), request.region->box ? "bbox" : "radius"),
                                    nlohmann::json::object());
    return region.points(request, values);
  });
}

}  // namespace slamvdb::fleet
