#include "slamvdb/query/map_query.hpp"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <queue>

#include "slamvdb/core/error.hpp"
#include "slamvdb/query/ann_index.hpp"
#include "slamvdb/query/class_confidence.hpp"

namespace slamvdb {
namespace {

constexpr std::size_t kGrain = 2048;  // cells per task: big enough to amortise, small enough to balance

// The index positions of the cells whose centre lies in `region`, read from the submaps whose
// world bounds meet it (GlobalIndex::cells_in_box).
std::vector<std::size_t> cells_of_region(const GlobalIndex& index, const QueryRegion& region) {
  std::vector<std::size_t> inside = index.cells_in_box(region.bounds());
  std::erase_if(inside, [&](std::size_t i) { return !region.contains(center_of_key(index.key(i), index.cell_size())); });
  return inside;
}

bool better(const ScoredCell& a, const ScoredCell& b) {
  if (a.score != b.score) return a.score > b.score;
  return a.cell < b.cell;
}

// Keeps the best k (all when k == 0) of what it is offered.
class TopK {
 public:
  explicit TopK(std::size_t k) : k_(k) {}
  void offer(const ScoredCell& c) {
    if (k_ == 0) return all_.push_back(c);
    if (heap_.size() < k_) {
      heap_.push(c);
    } else if (better(c, heap_.top())) {
      heap_.pop();
      heap_.push(c);
    }
  }
  void drain_into(std::vector<ScoredCell>& out) {
    out.insert(out.end(), all_.begin(), all_.end());
    all_.clear();
    for (; !heap_.empty(); heap_.pop()) out.push_back(heap_.top());
  }

 private:
  struct Worse {  // the heap's top is the worst kept
    bool operator()(const ScoredCell& a, const ScoredCell& b) const { return better(a, b); }
  };
  std::size_t k_;
  std::vector<ScoredCell> all_;
  std::priority_queue<ScoredCell, std::vector<ScoredCell>, Worse> heap_;
};

}  // namespace

void check_query_vector(const SemanticMap& map, std::span<const float> query) {
  const int dim = map.params().semantic.dim;
  if (static_cast<int>(query.size()) != dim)
    throw Error(fmt::format("the query has {} values but the map holds {}-d embeddings", query.size(), dim));
  if (!std::all_of(query.begin(), query.end(), [](float v) { return std::isfinite(v); }))
    throw Error("the query vector holds a NaN or infinite value");
  if (!unit_vector(query)) throw Error("the query vector is zero");
}

std::vector<ScoredCell> similarity_search(const SemanticMap& map, std::span<const float> query,
                                          const SearchOptions& options) {
  check_query_vector(map, query);
  const auto dim = query.size();
  const Eigen::VectorXf q = *unit_vector(query);  // no float overflow for huge components
  std::vector<ScoredCell> out;
  map.read_index([&](const GlobalIndex& index) {
    // With a region, the cells in it (read from the submaps whose bounds meet it); through an ANN
    // index, the cells it proposes; else all.
    std::vector<std::size_t> candidates;
    const bool approximate = searches_approximately(options);
    if (options.region) candidates = cells_of_region(index, *options.region);
    if (approximate) {
      if (options.ann->index_size() != index.size())
        throw Error(fmt::format("the ANN index was built over {} cells but the map now has {}: build it again",
                                options.ann->index_size(), index.size()));
      candidates = options.ann->candidates(std::span<const float>(q.data(), dim), options.ann_probes, options.top_k,
                                           nullptr, options.deadline);
    }
    const bool listed = options.region || approximate;
    const std::size_t n = listed ? candidates.size() : index.size();
    struct Local {
      TopK best;
      std::vector<float> scratch;
    };
    tbb::enumerable_thread_specific<Local> locals([&] { return Local{TopK(options.top_k), std::vector<float>(dim)}; });
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kGrain), [&](const auto& range) {
      options.deadline.check("scoring the map's cells");  // per chunk of at most kGrain cells
      Local& local = locals.local();
      for (std::size_t k = range.begin(); k != range.end(); ++k) {
        const std::size_t i = listed ? candidates[k] : k;
        const GlobalIndex::Parts v = index.parts(i, local.scratch.data());
        float dot, norm2;
        kernels::dot_and_squared_norm(v.embedding, q.data(), dim, &dot, &norm2);
        if (!(norm2 > 0) || !std::isfinite(norm2)) continue;
        const float score = dot / std::sqrt(norm2);
        if (!(score >= options.threshold)) continue;
        const IndexCellKey& cell = index.key(i);
        local.best.offer({cell, center_of_key(cell, index.cell_size()), score, v.count, v.stats, std::nullopt, 0.f});
      }
    });
    for (Local& local : locals) local.best.drain_into(out);
  });
  std::sort(out.begin(), out.end(), better);
  if (options.top_k && out.size() > options.top_k) out.resize(options.top_k);
  return out;
}

bool searches_approximately(const SearchOptions& options) {
  return options.ann && options.top_k > 0 && !options.region && options.threshold == -std::numeric_limits<float>::infinity();
}

void classify_results(const SemanticMap& map, const QuerySet& queries, std::span<ScoredCell> results,
                      const ClassifyOptions& options, ModelIdCheck model_check) {
  check_compatible(queries, map.params().semantic.dim, map.info().model_id, model_check);
  const QueryClassifier classifier(queries, options);
  std::vector<float> scratch(static_cast<std::size_t>(map.params().semantic.dim));
  map.read_index([&](const GlobalIndex& index) {
    for (ScoredCell& r : results) {
      const auto at = index.find(r.cell);
      if (!at) throw Error("a search result is not a cell of this map");
      // The cell read as classify_map reads it, so that the class and confidence are the same.
      const GlobalIndex::Parts v = index.parts(*at, scratch.data());
      QueryMatch m;
      classifier.classify_combined(&v.embedding, 1, &m);
      r.match = m;
      r.confidence = voxel_confidence(m, v.count, v.stats);
    }
  });
}

namespace {

// The cells `positions` of the index classified (all of them when null), in that order: each cell
// read and classified the same way whichever list it is in, so a region's rows equal the whole
// map's rows of the same cells.
std::vector<ClassifiedCell> classify_index_cells(const GlobalIndex& index, const QueryClassifier& classifier,
                                                 std::size_t dim, const std::vector<std::size_t>* positions,
                                                 const SessionOrder& sessions, const Deadline& deadline) {
  const std::size_t total = positions ? positions->size() : index.size();
  std::vector<ClassifiedCell> out(total);
  constexpr std::size_t kBatch = 256;
  struct Local {
    std::vector<float> means;  // one row per cell of the batch with more than two entries
    std::vector<CombinedView> rows;
    std::vector<QueryMatch> matches;
  };
  tbb::enumerable_thread_specific<Local> locals([&] {
    return Local{std::vector<float>(kBatch * dim), std::vector<CombinedView>(kBatch), std::vector<QueryMatch>(kBatch)};
  });
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, total, kBatch), [&](const auto& range) {
    Local& local = locals.local();
    for (std::size_t begin = range.begin(); begin < range.end(); begin += kBatch) {
      deadline.check("classifying the map's cells");
      const std::size_t n = std::min(kBatch, range.end() - begin);
      // Entries are read where the submaps store them (fp16); a cell shared by two submaps is
      // combined in registers, only cells of three or more get their mean written out.
      for (std::size_t j = 0; j < n; ++j) {
        const std::size_t at = positions ? (*positions)[begin + j] : begin + j;
        const GlobalIndex::Parts v = index.parts(at, local.means.data() + j * dim);
        local.rows[j] = v.embedding;
        const IndexCellKey& cell = index.key(at);
        out[begin + j] = {cell, center_of_key(cell, index.cell_size()), v.count, {}, v.stats};
        out[begin + j].last_session = last_session_of_cell(index, at, sessions);
      }
      classifier.classify_combined(local.rows.data(), n, local.matches.data());
      for (std::size_t j = 0; j < n; ++j) {
        ClassifiedCell& c = out[begin + j];
        c.match = local.matches[j];
        c.confidence = voxel_confidence(c.match, c.count, c.stats);
      }
    }
  });
  return out;
}

}  // namespace

int last_session_of_cell(const GlobalIndex& index, std::size_t cell, const SessionOrder& order) {
  int newest = -1;
  for (const GlobalIndex::EntryRef& r : index.refs(cell)) {
    const int s = index.layer(r.submap)->session_of(r.handle);
    newest = newest < 0 ? s : order.newest(newest, s);
  }
  return newest;
}

std::vector<int> last_sessions(const SemanticMap& map, std::span<const IndexCellKey> cells) {
  const SessionOrder order(map.info().sessions);
  std::vector<int> out(cells.size(), -1);
  map.read_index([&](const GlobalIndex& index) {
    for (std::size_t i = 0; i < cells.size(); ++i)
      if (const auto at = index.find(cells[i])) out[i] = last_session_of_cell(index, *at, order);
  });
  return out;
}

std::vector<ClassifiedCell> classify_map(const SemanticMap& map, const QuerySet& queries,
                                         const ClassifyOptions& options, ModelIdCheck model_check) {
  check_compatible(queries, map.params().semantic.dim, map.info().model_id, model_check);
  const QueryClassifier classifier(queries, options);
  std::vector<ClassifiedCell> out;
  map.read_index([&](const GlobalIndex& index) {
    out = classify_index_cells(index, classifier, static_cast<std::size_t>(map.params().semantic.dim), nullptr,
                               SessionOrder(map.info().sessions), options.deadline);
  });
  return out;
}

std::vector<ClassifiedCell> classify_region(const SemanticMap& map, const QuerySet& queries, const QueryRegion& region,
                                            const ClassifyOptions& options, ModelIdCheck model_check) {
  check_compatible(queries, map.params().semantic.dim, map.info().model_id, model_check);
  const QueryClassifier classifier(queries, options);
  std::vector<ClassifiedCell> out;
  map.read_index([&](const GlobalIndex& index) {
    const std::vector<std::size_t> inside = cells_of_region(index, region);  // as similarity_search finds them
    out = classify_index_cells(index, classifier, static_cast<std::size_t>(map.params().semantic.dim), &inside,
                               SessionOrder(map.info().sessions), options.deadline);
  });
  return out;
}

std::size_t count_region_cells(const SemanticMap& map, const QueryRegion& region) {
  std::size_t n = 0;
  map.read_index([&](const GlobalIndex& index) { n = cells_of_region(index, region).size(); });
  return n;
}

void sort_by_cell(std::vector<ClassifiedCell>& cells) {
  tbb::parallel_sort(cells.begin(), cells.end(), [](const ClassifiedCell& a, const ClassifiedCell& b) { return a.cell < b.cell; });
}

std::vector<PointQuery> query_points(const SemanticMap& map, std::span<const Vec3d> points_world,
                                     const QuerySet* queries, const ClassifyOptions& options, ModelIdCheck model_check,
                                     bool with_embeddings) {
  std::optional<QueryClassifier> classifier;
  if (queries) {
    check_compatible(*queries, map.params().semantic.dim, map.info().model_id, model_check);
    classifier.emplace(*queries, options);
  }
  const auto dim = static_cast<std::size_t>(map.params().semantic.dim);
  std::vector<PointQuery> out(points_world.size());
  const SessionOrder sessions(map.info().sessions);
  map.read_index([&](const GlobalIndex& index) {
    std::vector<float> scratch(dim), mean(dim);
    for (std::size_t i = 0; i < points_world.size(); ++i) {
      if (i % 1024 == 0) options.deadline.check("looking up points");
      PointQuery& q = out[i];
      q.point_world = points_world[i];
      if (!points_world[i].allFinite()) continue;
      if (!in_grid_extent(points_world[i] / index.cell_size())) continue;
      const auto at = index.find(index.cell_of(points_world[i]));
      if (!at) continue;
      const IndexedVoxel v = index.read(*at, scratch.data());
      q.stats = index.statistics(*at, scratch.data());  // scratch: the mean of a shared cell
      q.found = true;
      q.cell = v.cell;
      q.cell_centre = v.position_world;
      q.count = v.count;
      q.entries = v.entries;
      q.last_session = last_session_of_cell(index, *at, sessions);
      q.last_session_name = session_name(map.info().sessions, q.last_session);
      if (!with_embeddings && !classifier) continue;
      kernels::decode(v.embedding, mean.data(), dim);
      if (with_embeddings) q.embedding = mean;
      if (classifier) {
        QueryMatch m;
        classifier->classify(mean.data(), 1, &m);
        q.match = m;
        q.confidence = voxel_confidence(m, q.count, q.stats);
      }
    }
  });
  return out;
}

}  // namespace slamvdb
