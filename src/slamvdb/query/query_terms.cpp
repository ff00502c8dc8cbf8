#include "slamvdb/query/query_terms.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace query_terms_detail {

void check_vector(const QuerySpace& space, const Eigen::VectorXf& v, std::string_view what) {
  if (v.size() != space.dim)
    throw Error(fmt::format("{}: a {}-d vector, but the map's embeddings are {}-d", what, v.size(), space.dim));
  if (!std::all_of(v.data(), v.data() + v.size(), [](float x) { return std::isfinite(x); }))
    throw Error(fmt::format("{}: the vector holds a non-finite value", what));
}

}  // namespace query_terms_detail

Eigen::VectorXf build_query_vector(const QuerySpace& space, const QueryTerms& terms, const QueryTermSources& sources) {
  std::vector<Eigen::VectorXf> positive, negative;
  if (terms.uses_text()) {
    if (!sources.embed_text) throw Error("a text query needs a text encoder");
    for (const auto& t : terms.text) positive.push_back((*sources.embed_text)(t));
    for (const auto& t : terms.not_text) negative.push_back((*sources.embed_text)(t));
  }
  if (terms.uses_classes()) {
    if (!sources.queries) throw Error("a class query needs a query set");
    check_compatible(*sources.queries, space.dim, space.model_id, sources.model_check);
    const auto row = [&](const std::string& name) -> Eigen::VectorXf {
      const auto k = sources.queries->find(name);
      if (!k) throw Error(fmt::format("{} has no class '{}'", sources.queries_name, name));
      return sources.queries->vectors.row(*k).transpose();
    };
    for (const auto& c : terms.classes) positive.push_back(row(c));
    for (const auto& c : terms.not_classes) negative.push_back(row(c));
  }
  for (const auto& v : terms.vectors) query_terms_detail::check_vector(space, v, "a query vector"), positive.push_back(v);
  for (const auto& v : terms.not_vectors)
    query_terms_detail::check_vector(space, v, "a negative query vector"), negative.push_back(v);
  return composite_query(positive, negative);
}

}  // namespace slamvdb
