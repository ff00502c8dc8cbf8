#pragma once
// What the server reads a map through. Today a SemanticMap in memory (a saved map loaded once, or
// later the map a running `map --serve` builds); `serve --db URL` (fleet map, a later issue) will
// put a database-backed map behind the same interface, so the routes never touch a SemanticMap.
// Every call may come from several request threads at once: implementations are thread-safe.
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <span>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/query/query_terms.hpp"

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
  // similarity_search over the map (query/map_query.hpp), the CLI's function.
  virtual std::vector<ScoredCell> search(std::span<const float> query, const SearchOptions& options) const = 0;
  // query_points over the map (what `query --at` answers), with classes when `queries` is given.
  virtual std::vector<PointQuery> at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                     const ClassifyOptions& options, ModelIdCheck model_check) const = 0;
  // classify_results over the map, for answers that carry a class (a query set given to the server).
  virtual void classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                        ModelIdCheck model_check) const = 0;
};

// A SemanticMap in memory, read through its global index (SemanticMap's own locks make concurrent
// readers safe, also while a mapper writes to it).
class SemanticMapService final : public MapService {
 public:
  SemanticMapService(std::shared_ptr<const SemanticMap> map, nlohmann::json info);
  QuerySpace space() const override;
  std::size_t semantic_cells() const override;
  nlohmann::json info() const override { return info_; }
  std::vector<ScoredCell> search(std::span<const float> query, const SearchOptions& options) const override;
  void classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                ModelIdCheck model_check) const override;
  std::vector<PointQuery> at(std::span<const Vec3d> points_world, const QuerySet* queries,
                             const ClassifyOptions& options, ModelIdCheck model_check) const override;

 private:
  std::shared_ptr<const SemanticMap> map_;
  nlohmann::json info_;
};

// A saved map, loaded once and checked in full; its info is `info --json --check` of the file.
std::shared_ptr<SemanticMapService> open_map_file_service(const std::filesystem::path& path);

}  // namespace slamvdb
