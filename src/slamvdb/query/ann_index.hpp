#pragma once
// An approximate nearest-neighbour index over a map's semantic cells, for top-k questions that
// exact scoring cannot answer fast enough (issue 21, "Speed": `slamvdb serve` with many clients).
// An inverted file: faiss's spherical k-means groups the cells' unit embeddings into lists, and each
// list keeps its cells' positions and compact codes of their residuals to the list's centroid (one
// byte per dimension in two 4-bit planes, ann_index_codes.hpp) contiguously. A question streams the
// coarse plane of the lists whose centroids are most similar to it (skipping a list whose codes'
// ranges cannot reach the best kept so far), orders the best of that by the whole codes, and
// similarity_search scores the best few exactly from the map's own storage. Answers are therefore exact scores of a subset of the cells; what can be
// missed is a cell of a list not looked at, or one the codes ranked below the re-scored few (recall,
// measured in ann_index_test.cpp and docs/serve-design.md).
// faiss is a PRIVATE dependency of the query part: nothing of it shows here.
#include <atomic>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "slamvdb/core/deadline.hpp"
#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

struct AnnOptions {
  std::size_t lists = 0;              // k-means clusters; 0: about sqrt(cells) / 4, in 8..1024
  std::size_t probes = 0;             // lists looked at per question; 0: an eighth of the lists
  std::size_t training_cells = 0;     // the k-means sample (evenly spaced cells); 0: 64 per list
  int iterations = 12;                // k-means iterations
  // Cells re-scored exactly per question: the best rerank_factor * top_k (at least rerank_min) by
  // approximate score of the probed lists' codes. (s40: 2 x top_k ordered by the whole codes keeps
  // recall@100 at 1.000 on the bench map, as 4 x did, for 0.4 ms less per question; serve-design.md.)
  std::size_t rerank_factor = 2;
  std::size_t rerank_min = 128;
  // Cells ordered by their whole 8-bit codes per question: the best refine_factor * (the re-rank
  // count) by the coarse plane (4 bits per dimension) that is scanned for every probed cell.
  std::size_t refine_factor = 3;
  // Set by another thread to stop a build early (the constructor then throws Error). Null: never.
  const std::atomic<bool>* stop = nullptr;
};

struct AnnIndexStats {
  std::size_t cells = 0;         // cells indexed (the map's semantic cells with a non-zero embedding)
  std::size_t lists = 0;
  std::size_t probes = 0;        // default lists looked at per question
  double build_seconds = 0;
  double training_seconds = 0;   // the k-means part of build_seconds
  std::size_t memory_bytes = 0;  // centroids + cell positions + codes
};

class AnnIndex {
 public:
  // Built over the map's global index as it is now. Embeddings of finished submaps do not change;
  // a map that gains or loses cells afterwards needs a new index (similarity_search refuses a
  // stale one). Throws Error for a map without semantic cells.
  explicit AnnIndex(const SemanticMap& map, const AnnOptions& options = {});
  ~AnnIndex();
  AnnIndex(const AnnIndex&) = delete;
  AnnIndex& operator=(const AnnIndex&) = delete;

  // The global-index positions of the cells to score exactly for the best `top_k` of `unit_query`
  // (dim floats, norm 1): of the cells of the `probes` (0: the default) most similar lists (more
  // lists while they hold fewer than `top_k` cells), the re-rank count best by their codes. In
  // ascending position (the order the global index holds them). `scanned`: coarse codes scored.
  // `deadline` is checked before each list: once it passes, DeadlineExceeded is thrown.
  std::vector<std::size_t> candidates(std::span<const float> unit_query, std::size_t probes, std::size_t top_k,
                                      std::size_t* scanned = nullptr, const Deadline& deadline = {}) const;
  // Cells of the global index the index was built over (its size then).
  std::size_t index_size() const;
  AnnIndexStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace slamvdb
