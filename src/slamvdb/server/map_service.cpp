#include "slamvdb/server/map_service.hpp"

#include <spdlog/spdlog.h>

#include "slamvdb/core/error.hpp"

#include "slamvdb/io/map_info_json.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb {

SemanticMapService::SemanticMapService(std::shared_ptr<const SemanticMap> map, nlohmann::json info,
                                       std::unique_ptr<AnnIndex> ann)
    : map_(std::move(map)), info_(std::move(info)), ann_(std::move(ann)), state_(ann_ ? "ready" : "none") {}

SemanticMapService::~SemanticMapService() {
  stop_build_ = true;
  if (builder_.joinable()) builder_.join();
}

void SemanticMapService::build_index_in_background(IndexBuilder build) {
  {
    const std::lock_guard lock(ann_mutex_);
    if (state_ != "none") throw Error("SemanticMapService: an ANN index is already built or being built");
    state_ = "building";
  }
  builder_ = std::thread([this, build = std::move(build)] {
    std::shared_ptr<const AnnIndex> index;
    std::string state = "ready";
    try {
      index = build(*map_, stop_build_);
      const AnnIndexStats s = index->stats();
      spdlog::info("ANN index: {} cells in {} lists ({} looked at per query), {:.1f} MB, built in {:.2f} s "
                   "(k-means {:.2f} s); top-k queries now go through it",
                   s.cells, s.lists, s.probes, static_cast<double>(s.memory_bytes) / 1e6, s.build_seconds,
                   s.training_seconds);
    } catch (const std::exception& e) {
      if (!stop_build_) spdlog::error("ANN index: not built ({}); every query is scored exactly", e.what());
      state = "failed";
      index.reset();
    }
    spdlog::default_logger()->flush();  // no later line may come to push it out of a buffered stdout
    const std::lock_guard lock(ann_mutex_);
    ann_ = std::move(index);
    state_ = state;
    ann_built_.notify_all();
  });
}

bool SemanticMapService::wait_for_index(std::chrono::milliseconds timeout) const {
  std::unique_lock lock(ann_mutex_);
  return ann_built_.wait_for(lock, timeout, [this] { return state_ != "building"; });
}

std::string SemanticMapService::index_state() const {
  const std::lock_guard lock(ann_mutex_);
  return state_;
}

std::shared_ptr<const AnnIndex> SemanticMapService::ann() const {
  const std::lock_guard lock(ann_mutex_);
  return ann_;
}

QuerySpace SemanticMapService::space() const { return {map_->params().semantic.dim, map_->info().model_id}; }

std::size_t SemanticMapService::semantic_cells() const { return map_->num_index_cells(); }

MapService::SearchAnswer SemanticMapService::search(std::span<const float> query, const SearchOptions& options,
                                                    bool exact) const {
  const std::shared_ptr<const AnnIndex> index = exact ? nullptr : ann();
  SearchOptions o = options;
  o.ann = index.get();
  const bool approximate = searches_approximately(o);
  return {similarity_search(*map_, query, o), approximate};
}

MapService::SearchAnswer MapService::search_and_classify(std::span<const float> query, const SearchOptions& options,
                                                         bool exact, const QuerySet* queries,
                                                         const ClassifyOptions& classify_options,
                                                         ModelIdCheck model_check) const {
  SearchAnswer found = search(query, options, exact);
  if (queries) classify(*queries, found.cells, classify_options, model_check);
  return found;
}

void SemanticMapService::classify(const QuerySet& queries, std::span<ScoredCell> results,
                                  const ClassifyOptions& options, ModelIdCheck model_check) const {
  classify_results(*map_, queries, results, options, model_check);
}

std::vector<PointQuery> SemanticMapService::at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                               const ClassifyOptions& options, ModelIdCheck model_check,
                                               bool with_embeddings) const {
  return query_points(*map_, points_world, queries, options, model_check, with_embeddings);
}

std::vector<ClassifiedCell> SemanticMapService::classes(const QuerySet& queries, const QueryRegion& region,
                                                        const ClassifyOptions& options, ModelIdCheck model_check) const {
  std::vector<ClassifiedCell> cells = classify_region(*map_, queries, region, options, model_check);
  sort_by_cell(cells);
  return cells;
}

std::size_t SemanticMapService::region_cells(const QueryRegion& region) const {
  return count_region_cells(*map_, region);
}

MapService::RegionGrid SemanticMapService::nav_grid(const QuerySet& queries, const NavGridOptions& options,
                                                    const ClassifyOptions& classify, ModelIdCheck model_check) const {
  if (!options.region) throw Error("SemanticMapService::nav_grid needs a region");
  std::vector<ClassifiedCell> cells = classify_region(*map_, queries, *options.region, classify, model_check);
  sort_by_cell(cells);  // as classify sorts them before building its grid
  return {build_nav_grid(*map_, cells, options), submap_path(*map_)};
}

double SemanticMapService::grid_resolution() const { return map_->params().index_cell(); }

std::shared_ptr<SemanticMapService> open_map_file_service(const std::filesystem::path& path, const AnnOptions* ann,
                                                          std::size_t ann_min_cells) {
  const MapFileSummary summary = read_map_summary(path);
  auto map = std::make_shared<const SemanticMap>(load_map(path));
  nlohmann::json info = map_info_json(path.string(), summary, map_world_figures(*map));
  auto service = std::make_shared<SemanticMapService>(std::move(map), std::move(info));
  if (ann && service->semantic_cells() > 0 && service->semantic_cells() >= ann_min_cells) {
    spdlog::info("ANN index: building over {} cells; queries are scored exactly until it is ready",
                 service->semantic_cells());
    service->build_index_in_background([options = *ann](const SemanticMap& m, const std::atomic<bool>& stop) {
      AnnOptions o = options;
      o.stop = &stop;
      return std::make_unique<AnnIndex>(m, o);
    });
  }
  return service;
}

}  // namespace slamvdb
