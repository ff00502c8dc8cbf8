#pragma once
// The terms of one similarity question (paper Figure 6.2), as every front end gives them: texts,
// classes of a query set and raw vectors, each positive or negative. `slamvdb query` and
// `slamvdb serve` both turn their input into QueryTerms and ask build_query_vector for the one
// vector they search with, so the two can never disagree on what a question means.
// Images are embedded by the front end (it owns the image encoder) and come in as vectors.
#include <Eigen/Core>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/query/query_set.hpp"

namespace slamvdb {

struct QueryTerms {
  std::vector<std::string> text, not_text;        // embedded by the text embedder
  std::vector<std::string> classes, not_classes;  // rows of a query set
  std::vector<Eigen::VectorXf> vectors, not_vectors;

  bool has_positive() const { return !text.empty() || !classes.empty() || !vectors.empty(); }
  bool uses_text() const { return !text.empty() || !not_text.empty(); }
  bool uses_classes() const { return !classes.empty() || !not_classes.empty(); }
};

// The embedding of one text in the map's space (the caller's encoder, or a cache in front of it).
using TextEmbedder = std::function<Eigen::VectorXf(std::string_view text)>;

// What a question is asked against: the map's embedding space.
struct QuerySpace {
  int dim = 0;
  std::string model_id;
};

// Where the terms come from, for messages: the query set's name (its file) when classes are used.
struct QueryTermSources {
  const TextEmbedder* embed_text = nullptr;  // needed when terms use text
  const QuerySet* queries = nullptr;         // needed when terms use classes
  std::string queries_name = "the query set";
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;  // for the query set
};

// The composite query vector (composite_query: unit terms, positives minus negatives, normalised).
// Throws Error naming what is wrong: a class the query set lacks, a vector of the wrong dimension
// or with a non-finite value, a query set of another space, no positive term, terms that cancel.
// The text embedder's space is checked by the caller (it knows the encoder's model id).
Eigen::VectorXf build_query_vector(const QuerySpace& space, const QueryTerms& terms, const QueryTermSources& sources);

}  // namespace slamvdb
