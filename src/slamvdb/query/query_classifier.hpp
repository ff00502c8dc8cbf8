#pragma once
// The classification rule the map side runs on chunks of voxel embeddings (and the per-image
// baseline on pixels): cosine similarity with every query, best class wins, and a void class
// never wins (paper section 6.3.2: "the second highest similarity class is used for voxels
// initially classified as Void"). Taking the second-best when void is best is the same as taking
// the best non-void class, which is what is computed.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "slamvdb/core/deadline.hpp"
#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/query/query_set.hpp"

namespace slamvdb {

inline constexpr int32_t kNoClass = -1;

struct QueryMatch {
  int32_t class_index = kNoClass;  // into the query set; kNoClass for zero or non-finite embeddings
  float score = 0.f;               // cosine of the embedding with the chosen class's query
  // score minus the cosine of the runner-up among the classes that could have been chosen (void
  // excluded under the rule); +inf when only one class could be chosen; 0 with kNoClass.
  float margin = 0.f;
};

struct ClassifyOptions {
  bool void_to_second_best = true;  // the paper's rule; off: void classes can win
  bool portable_kernel = false;     // force the plain Eigen kernel (tests and benchmarks compare)
  // For the map-wide questions that classify (classify_map / classify_region / query_points):
  // checked between batches of cells or points; once it passes they throw DeadlineExceeded
  // (serve's --time-budget). The classifier itself ignores it. Default: never.
  Deadline deadline{};
};

class QueryClassifier {
 public:
  // Throws Error if the query set is invalid.
  explicit QueryClassifier(const QuerySet& queries, ClassifyOptions options = {});

  int dim() const { return static_cast<int>(queries_.cols()); }
  int num_classes() const { return num_classes_; }

  // `embeddings`: rows x dim fp32, row-major, any norm. out[i] for row i. Parallel (TBB) over
  // chunks of rows; each row's result depends only on that row (same output for any thread count).
  void classify(const float* embeddings, std::size_t rows, QueryMatch* out) const;
  // Throws Error unless embeddings.size() is a multiple of dim().
  std::vector<QueryMatch> classify(std::span<const float> embeddings) const;
  // Rows wherever they are stored, fp16 or fp32 (a map's entries, read in place); single-threaded,
  // for callers that split the work themselves.
  void classify_views(const EmbeddingView* rows, std::size_t count, QueryMatch* out) const;
  // Rows given as the weighted sum of one or two stored rows (an index cell shared by submaps),
  // combined in registers.
  void classify_combined(const CombinedView* rows, std::size_t count, QueryMatch* out) const;

  // Whether the AVX2 + FMA kernel runs (chosen at run time; the Eigen kernel otherwise).
  bool uses_avx2() const { return use_avx2_; }

 private:
  // rows <= 256; dots (rows x classes) and norm2 (rows) are scratch.
  void classify_chunk(const float* embeddings, std::size_t rows, QueryMatch* out, float* dots, float* norm2) const;
  // The rule on rows x classes dot products (with unit queries) and the rows' squared norms.
  void decide(const float* dots, const float* norm2, std::size_t rows, QueryMatch* out) const;

  QueryMatrix queries_;             // unit rows of the classes that may be the answer
  std::vector<int> class_of_row_;   // row of queries_ -> class index
  int num_classes_ = 0;
  bool use_avx2_ = false;
  bool use_f16c_ = false;
};

// The same as one call: QueryClassifier(queries, options).classify(...). Callers that classify many
// chunks should keep a QueryClassifier (it normalises the queries once).
std::vector<QueryMatch> classify_embeddings(std::span<const float> embeddings, const QuerySet& queries,
                                            const ClassifyOptions& options = {});

}  // namespace slamvdb
