#include "slamvdb/server/map_service.hpp"

#include "slamvdb/io/map_info_json.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb {

SemanticMapService::SemanticMapService(std::shared_ptr<const SemanticMap> map, nlohmann::json info)
    : map_(std::move(map)), info_(std::move(info)) {}

QuerySpace SemanticMapService::space() const { return {map_->params().semantic.dim, map_->info().model_id}; }

std::size_t SemanticMapService::semantic_cells() const { return map_->num_index_cells(); }

std::vector<ScoredCell> SemanticMapService::search(std::span<const float> query, const SearchOptions& options) const {
  return similarity_search(*map_, query, options);
}

void SemanticMapService::classify(const QuerySet& queries, std::span<ScoredCell> results,
                                  const ClassifyOptions& options, ModelIdCheck model_check) const {
  classify_results(*map_, queries, results, options, model_check);
}

std::vector<PointQuery> SemanticMapService::at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                               const ClassifyOptions& options, ModelIdCheck model_check) const {
  return query_points(*map_, points_world, queries, options, model_check);
}

std::shared_ptr<SemanticMapService> open_map_file_service(const std::filesystem::path& path) {
  const MapFileSummary summary = read_map_summary(path);
  auto map = std::make_shared<const SemanticMap>(load_map(path));
  nlohmann::json info = map_info_json(path.string(), summary, map_world_figures(*map));
  return std::make_shared<SemanticMapService>(std::move(map), std::move(info));
}

}  // namespace slamvdb
