#include "slamvdb/server/map_service.hpp"

#include <spdlog/spdlog.h>

#include "slamvdb/io/map_info_json.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb {

SemanticMapService::SemanticMapService(std::shared_ptr<const SemanticMap> map, nlohmann::json info,
                                       std::unique_ptr<AnnIndex> ann)
    : map_(std::move(map)), info_(std::move(info)), ann_(std::move(ann)) {}

QuerySpace SemanticMapService::space() const { return {map_->params().semantic.dim, map_->info().model_id}; }

std::size_t SemanticMapService::semantic_cells() const { return map_->num_index_cells(); }

MapService::SearchAnswer SemanticMapService::search(std::span<const float> query, const SearchOptions& options,
                                                    bool exact) const {
  SearchOptions o = options;
  o.ann = exact ? nullptr : ann_.get();
  const bool approximate = searches_approximately(o);
  return {similarity_search(*map_, query, o), approximate};
}

void SemanticMapService::classify(const QuerySet& queries, std::span<ScoredCell> results,
                                  const ClassifyOptions& options, ModelIdCheck model_check) const {
  classify_results(*map_, queries, results, options, model_check);
}

std::vector<PointQuery> SemanticMapService::at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                               const ClassifyOptions& options, ModelIdCheck model_check) const {
  return query_points(*map_, points_world, queries, options, model_check);
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
  std::unique_ptr<AnnIndex> index;
  if (ann && map->num_index_cells() > 0 && map->num_index_cells() >= ann_min_cells) {
    index = std::make_unique<AnnIndex>(*map, *ann);
    const AnnIndexStats s = index->stats();
    spdlog::info("ANN index: {} cells in {} lists ({} looked at per query), {:.1f} MB, built in {:.2f} s", s.cells,
                 s.lists, s.probes, static_cast<double>(s.memory_bytes) / 1e6, s.build_seconds);
  }
  return std::make_shared<SemanticMapService>(std::move(map), std::move(info), std::move(index));
}

}  // namespace slamvdb
