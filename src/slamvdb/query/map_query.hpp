#pragma once
// Retrieval over the map (paper section 6.2.5): every question reads the map through its global
// index (world frame, count-weighted across submaps), as matrix products over the index's cells
// rather than one look-up per voxel: similarity search with one query vector (raw, text, image or
// composite), classification of every cell against a query set, and questions about given points.
#include <Eigen/Core>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "slamvdb/core/deadline.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/query/query_classifier.hpp"
#include "slamvdb/query/query_region.hpp"
#include "slamvdb/query/query_set.hpp"

namespace slamvdb {

class AnnIndex;  // query/ann_index.hpp

// One cell of the index with its cosine similarity to a query, and what the map knows of it.
struct ScoredCell {
  IndexCellKey cell;
  Vec3d position_world;  // cell centre
  float score = 0.f;     // cosine similarity, -1..1
  uint32_t count = 0;    // observations fused into the cell
  VoxelStatistics stats{};  // its observations' weight and spread (spread NaN: map before format 3)
  std::optional<QueryMatch> match;  // its class against a query set (classify_results)
  float confidence = 0.f;           // voxel_confidence of the match (with a query set)
};

struct SearchOptions {
  std::size_t top_k = 0;                                     // 0: every cell above the threshold
  float threshold = -std::numeric_limits<float>::infinity();  // keep cells with score >= threshold
  // Only cells whose centre lies in the region: submaps whose world bounds miss it are not read,
  // the cells of the others are tested exactly, and only those inside are scored
  // (GlobalIndex::cells_in_box). The answer is the unrestricted one's cells in the region.
  std::optional<QueryRegion> region;
  // An approximate nearest-neighbour index of this map (query/ann_index.hpp): a top_k question
  // without threshold or region scores only the cells it proposes (exactly, as below), so the
  // answer is exact scores of a subset that may miss a cell (searches_approximately). Questions
  // with a threshold or a region always scan every cell they concern. Null: exact.
  const AnnIndex* ann = nullptr;
  std::size_t ann_probes = 0;  // lists the index looks at (0: its default)
  // Checked between chunks of cells (and of the index's lists): once it passes, the search stops
  // and throws DeadlineExceeded (serve's --time-budget). Default: never.
  Deadline deadline{};
};

// Whether similarity_search answers `options` through options.ann.
bool searches_approximately(const SearchOptions& options);

// Cells by decreasing similarity with `query` (any norm; dim = the map's), ties by cell key. Cells
// whose embedding is zero or not finite have no similarity and are left out. Parallel (TBB).
// Throws Error on a query of the wrong dimension or a zero / non-finite query. A region outside
// the map answers no cells.
std::vector<ScoredCell> similarity_search(const SemanticMap& map, std::span<const float> query,
                                          const SearchOptions& options = {});

// Gives each result its best class of `queries` and that class's voxel_confidence, as query_points
// and classify_map would at the same cell (results of similarity_search on the same map). Checks
// the query set against the map as classify_map does.
void classify_results(const SemanticMap& map, const QuerySet& queries, std::span<ScoredCell> results,
                      const ClassifyOptions& options = {}, ModelIdCheck model_check = ModelIdCheck::kRequireMatch);

// One cell of the index classified against a query set.
struct ClassifiedCell {
  IndexCellKey cell;
  Vec3d position_world;
  uint32_t count = 0;
  QueryMatch match;  // class (into the query set), cosine score, margin to the runner-up
  VoxelStatistics stats{};  // its observations' weight and spread (spread NaN: map before format 3)
  float confidence = 0.f;   // voxel_confidence (query/class_confidence.hpp), 0..1
  int last_session = 0;     // the newest session that observed it (SessionInfo::id)
};

// The newest session that observed any entry of index cell `cell` (its submaps' entries' last-
// observed sessions, SemanticLayer::session_of, ordered by `order`).
int last_session_of_cell(const GlobalIndex& index, std::size_t cell, const SessionOrder& order);
// The same for cells by key (-1 for a key that is not a cell of the map).
std::vector<int> last_sessions(const SemanticMap& map, std::span<const IndexCellKey> cells);

// A cell classified below a confidence threshold (classify --min-confidence): its class is shown as
// `uncertain`. Cells without a class are not uncertain, they have none.
inline bool is_uncertain(const ClassifiedCell& c, float min_confidence) {
  return c.match.class_index != kNoClass && c.confidence < min_confidence;
}

// Every semantic cell of the map, at its position in the index (result i is GlobalIndex cell i;
// sort_by_cell gives the order outputs are written in). Checks the query set against the map
// (dimension, and model id unless `model_check` is kIgnore).
std::vector<ClassifiedCell> classify_map(const SemanticMap& map, const QuerySet& queries,
                                         const ClassifyOptions& options = {},
                                         ModelIdCheck model_check = ModelIdCheck::kRequireMatch);

// classify_map limited to the cells whose centre lies in `region` (classify --bbox / --near, GET
// /api/classes): the same rows as classify_map's for those cells; submaps whose world bounds miss
// the region are not read. Any order (sort_by_cell for outputs).
std::vector<ClassifiedCell> classify_region(const SemanticMap& map, const QuerySet& queries, const QueryRegion& region,
                                            const ClassifyOptions& options = {},
                                            ModelIdCheck model_check = ModelIdCheck::kRequireMatch);

// How many semantic cells classify_region would answer for `region` (the same cells, nothing
// classified): lets a caller refuse a region too large to answer before doing the work.
std::size_t count_region_cells(const SemanticMap& map, const QueryRegion& region);

// Cell-key order: the same map always gives the same list, whatever the history of its index.
void sort_by_cell(std::vector<ClassifiedCell>& cells);

// What the map holds at a world point.
struct PointQuery {
  Vec3d point_world;
  bool found = false;         // false: no semantic cell there
  IndexCellKey cell;
  Vec3d cell_centre = Vec3d::Zero();
  uint32_t count = 0;
  uint32_t entries = 0;       // submap entries averaged into the cell
  std::vector<float> embedding;  // the cell's count-weighted mean, fp32 (empty unless asked for)
  VoxelStatistics stats{};      // the cell's observation statistics (spread NaN: map before format 3)
  std::optional<QueryMatch> match;  // with a query set
  float confidence = 0.f;       // voxel_confidence of the match (with a query set)
  int last_session = 0;         // the newest session that observed the cell (when found)
  std::string last_session_name;  // its name (session_name)
};

// `with_embeddings`: fill PointQuery::embedding (2 KB per 512-d point: left out where the caller
// does not use it, e.g. `query --at`'s CSV and POST /api/at without "embedding": true).
std::vector<PointQuery> query_points(const SemanticMap& map, std::span<const Vec3d> points_world,
                                     const QuerySet* queries = nullptr, const ClassifyOptions& options = {},
                                     ModelIdCheck model_check = ModelIdCheck::kRequireMatch,
                                     bool with_embeddings = true);

// The map's embedding-space check for a vector that did not come from a query set.
void check_query_vector(const SemanticMap& map, std::span<const float> query);

}  // namespace slamvdb
