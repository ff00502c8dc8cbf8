#pragma once
// An approximate nearest-neighbour index over a map's semantic cells, for top-k questions that
// exact scoring cannot answer fast enough (issue 21, "Speed": `slamvdb serve` with many clients).
// An inverted file: faiss's spherical k-means groups the cells' unit embeddings into lists; a
// question looks only at the cells of the lists whose centroids are most similar to it, and
// similarity_search scores those cells exactly, from the map's own storage (no second copy of
// the embeddings: the index holds the centroids and one 4-byte cell position per cell). Answers
// are therefore exact scores of a subset of the cells; what can be missed is a cell of a list not
// looked at (recall, measured in ann_index_test.cpp and docs/serve-design.md).
// faiss is a PRIVATE dependency of the query part: nothing of it shows here.
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

struct AnnOptions {
  std::size_t lists = 0;              // k-means clusters; 0: about sqrt(cells) / 4, in 8..1024
  std::size_t probes = 0;             // lists looked at per question; 0: an eighth of the lists
  std::size_t training_cells = 65536; // the k-means sample (evenly spaced cells)
  int iterations = 12;                // k-means iterations
};

struct AnnIndexStats {
  std::size_t cells = 0;         // cells indexed (the map's semantic cells with a non-zero embedding)
  std::size_t lists = 0;
  std::size_t probes = 0;        // default lists looked at per question
  double build_seconds = 0;
  std::size_t memory_bytes = 0;  // centroids + cell positions
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

  // The global-index positions of the cells to score for `unit_query` (dim floats, norm 1): the
  // cells of the `probes` (0: the default) most similar lists, more lists while they hold fewer
  // than `min_cells` cells. In ascending position (the order the global index holds them).
  std::vector<std::size_t> candidates(std::span<const float> unit_query, std::size_t probes,
                                      std::size_t min_cells) const;
  // Cells of the global index the index was built over (its size then).
  std::size_t index_size() const;
  AnnIndexStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace slamvdb
