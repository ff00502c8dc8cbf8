#include "slamvdb/query/query_set.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"

namespace slamvdb {

std::optional<int> QuerySet::find(std::string_view name) const {
  for (std::size_t k = 0; k < names.size(); ++k)
    if (names[k] == name) return static_cast<int>(k);
  return std::nullopt;
}

bool QuerySet::is_void(int k) const {
  return std::find(void_classes.begin(), void_classes.end(), k) != void_classes.end();
}

void QuerySet::validate(std::string_view where) const {
  const auto fail = [&](const std::string& what) { throw Error(fmt::format("{}: {}", where, what)); };
  if (model_id.empty()) fail("the query set has no model id (the embedding space its vectors belong to)");
  if (names.empty()) fail("the query set has no classes");
  if (vectors.rows() != static_cast<Eigen::Index>(names.size()))
    fail(fmt::format("{} class names but {} vectors", names.size(), vectors.rows()));
  if (vectors.cols() < 1) fail("the query vectors have dimension 0");
  std::set<std::string_view> seen;
  for (std::size_t k = 0; k < names.size(); ++k) {
    // Names reach CSV files, terminals and markdown tables: bounded here, where every query set
    // passes (loaded, imported, trained, or made by a program).
    if (const std::string problem = display_name_problem(names[k]); !problem.empty())
      fail(fmt::format("the name of class {} '{}' {} ({})", k + 1, escape_control(names[k], kMaxDisplayNameBytes),
                       problem, kDisplayNameRule));
    if (!seen.insert(names[k]).second) fail(fmt::format("class name '{}' appears twice", names[k]));
    const auto row = vectors.row(static_cast<Eigen::Index>(k));
    if (!row.allFinite()) fail(fmt::format("the vector of class '{}' has a NaN or infinite value", names[k]));
    if (row.cwiseAbs().maxCoeff() == 0.f) fail(fmt::format("the vector of class '{}' is zero", names[k]));
  }
  if (!colours.empty() && colours.size() != names.size())
    fail(fmt::format("{} colours for {} classes", colours.size(), names.size()));
  std::set<int> voids;
  for (int k : void_classes) {
    if (k < 0 || k >= size()) fail(fmt::format("void class index {} is out of range [0, {})", k, size()));
    if (!voids.insert(k).second) fail(fmt::format("void class '{}' is listed twice", names[k]));
  }
  if (static_cast<int>(voids.size()) == size()) fail("every class is void: no class would be left to answer");
}

QuerySet make_query_set(const Ontology& ontology, QueryMatrix vectors, std::string model_id) {
  QuerySet q;
  q.model_id = std::move(model_id);
  q.names = ontology.class_names();
  q.vectors = std::move(vectors);
  for (const auto& c : ontology.classes()) q.colours.push_back(c.rgb);
  q.void_classes = ontology.void_classes();
  q.validate("query set for ontology " + ontology.name());
  return q;
}

void check_compatible(const QuerySet& queries, int map_dim, std::string_view map_model_id, ModelIdCheck model_check) {
  if (queries.dim() != map_dim)
    throw Error(fmt::format("the query vectors are {}-d ({}) but the map's embeddings are {}-d ({}): queries must "
                            "come from the map's embedding model",
                            queries.dim(), queries.model_id, map_dim, map_model_id));
  if (model_check == ModelIdCheck::kRequireMatch && queries.model_id != map_model_id)
    throw Error(fmt::format("the query vectors belong to model '{}' but the map was built with '{}': similarities "
                            "across embedding spaces are meaningless (override only if both ids name the same space)",
                            queries.model_id, map_model_id));
}

std::vector<int> ontology_classes_of(const QuerySet& queries, const Ontology& ontology) {
  std::vector<int> classes;
  std::vector<std::string> missing;
  for (const auto& name : queries.names) {
    const auto k = ontology.find_class(name);
    if (!k) missing.push_back(name);
    classes.push_back(k.value_or(-1));
  }
  if (!missing.empty())
    throw Error(fmt::format("queries {} are no class of ontology '{}' (classes: {})", fmt::join(missing, ", "),
                            ontology.name(), fmt::join(ontology.class_names(), ", ")));
  return classes;
}

std::optional<Eigen::VectorXf> unit_vector(std::span<const float> v) {
  double n2 = 0;
  for (const float x : v) n2 += static_cast<double>(x) * x;
  if (!std::isfinite(n2) || !(n2 > 0)) return std::nullopt;
  const double inv = 1.0 / std::sqrt(n2);
  Eigen::VectorXf unit(static_cast<Eigen::Index>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) unit[static_cast<Eigen::Index>(i)] = static_cast<float>(v[i] * inv);
  return unit;
}

Eigen::VectorXf composite_query(const std::vector<Eigen::VectorXf>& positive,
                                const std::vector<Eigen::VectorXf>& negative) {
  if (positive.empty()) throw Error("a composite query needs at least one positive term");
  const Eigen::Index dim = positive.front().size();
  Eigen::VectorXf sum = Eigen::VectorXf::Zero(dim);
  const auto add = [&](const Eigen::VectorXf& term, float sign, const char* kind, std::size_t i) {
    if (term.size() != dim)
      throw Error(fmt::format("{} term {} is {}-d, the first positive term {}-d", kind, i + 1, term.size(), dim));
    if (!term.allFinite()) throw Error(fmt::format("{} term {} has a NaN or infinite value", kind, i + 1));
    const auto unit = unit_vector({term.data(), static_cast<std::size_t>(term.size())});
    if (!unit) throw Error(fmt::format("{} term {} is a zero vector", kind, i + 1));
    sum += sign * *unit;
  };
  for (std::size_t i = 0; i < positive.size(); ++i) add(positive[i], 1.f, "positive", i);
  for (std::size_t i = 0; i < negative.size(); ++i) add(negative[i], -1.f, "negative", i);
  // The terms are unit vectors, so the sum is at most their number long: no overflow here. Terms
  // that cancel (the same text positive and negative) leave rounding noise, not a direction.
  const float norm = sum.norm();
  if (!(norm > 1e-4f)) throw Error("the composite query's terms cancel out: the result is a zero vector");
  return sum / norm;
}

}  // namespace slamvdb
