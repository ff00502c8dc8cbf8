#pragma once
// A query set: n named vectors in one embedding space (paper section 6.2.5: one trained query per
// class of the ontology), with the class colours, which classes are void (a voxel whose best class
// is void takes its second-best, section 6.3.2) and how the vectors were made.
//
// File (.json, self-describing): {"format": "slamvdb-query-set", "version": 1, "model_id", "dim",
// "classes": [{"name", "rgb": [r, g, b] (optional), "void": bool, "vector": [dim numbers]}],
// "provenance": {...}}. Every float is written as the exact decimal of its double value, so a
// save/load round trip gives the same bits.
#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/ontology/ontology.hpp"

namespace slamvdb {

using QueryMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;  // n x dim

struct QueryProvenance {
  std::string method;  // "train-queries", "csv-import", "text", ...
  std::optional<int> epochs;
  std::optional<double> learning_rate, temperature;
  std::optional<uint64_t> seed;
  std::optional<double> accuracy;            // validation pixel accuracy after training, 0..1
  std::map<std::string, std::string> notes;  // dataset, ontology, initialisation, ...
};

struct QuerySet {
  std::string model_id;  // the embedding space (encoder) the vectors belong to
  std::vector<std::string> names;
  QueryMatrix vectors;
  std::vector<Rgb8> colours;      // one per class, or empty
  std::vector<int> void_classes;  // indices, ascending
  QueryProvenance provenance;

  int size() const { return static_cast<int>(names.size()); }
  int dim() const { return static_cast<int>(vectors.cols()); }
  std::optional<int> find(std::string_view name) const;
  bool is_void(int k) const;
  // Throws Error (prefixed with `where`) unless: >= 1 class, unique names that follow the rule of
  // display_name_problem (core/text_escape.hpp: at most 64 bytes, no control characters), one row
  // per name, dim >= 1, finite non-zero rows, colours empty or one per class, void indices valid,
  // unique and not all classes, a non-empty model id.
  void validate(std::string_view where) const;
};

// Names, colours and void classes from the ontology (class order), vectors as given.
QuerySet make_query_set(const Ontology& ontology, QueryMatrix vectors, std::string model_id);

// Throws Error naming the file: unreadable, not JSON, another format, a newer version, missing or
// malformed fields, wrong vector lengths, non-finite values.
void save_query_set(const std::filesystem::path& file, const QuerySet& queries);
QuerySet load_query_set(const std::filesystem::path& file);

// The authors' prototype layout: one FILE.csv per class holding one line of `dim` comma-separated
// floats; the class name is the file stem. With an ontology, every class must have a file and
// every file a class (case-insensitive), and order, colours and void classes come from it;
// without, classes are sorted by name and none is void. Errors name the file, line and column.
QuerySet import_query_csv_dir(const std::filesystem::path& dir, std::string model_id,
                              const Ontology* ontology = nullptr);
// One NAME.csv per class, values printed with 9 significant digits (exact for float).
void export_query_csv_dir(const QuerySet& queries, const std::filesystem::path& dir);

// The map side refuses queries from another embedding space: throws Error when the dimension
// differs, or the model id differs unless `model_check` is kIgnore (for users who know that two
// ids name the same space, e.g. a re-exported network).
enum class ModelIdCheck { kRequireMatch, kIgnore };
void check_compatible(const QuerySet& queries, int map_dim, std::string_view map_model_id,
                      ModelIdCheck model_check = ModelIdCheck::kRequireMatch);

// Query index -> class index in `ontology`, matched by name. Throws Error naming the queries
// that are no class of the ontology.
std::vector<int> ontology_classes_of(const QuerySet& queries, const Ontology& ontology);

// `v / |v|` with the norm summed in double: in float the sum of squares overflows to infinity for
// components beyond ~1e19 (a 1e30 vector became a "zero vector") and underflows to zero below
// ~1e-19; in double no finite float vector does either. nullopt for a zero or non-finite vector.
std::optional<Eigen::VectorXf> unit_vector(std::span<const float> v);

// Paper Figure 6.2: one query from positive and negative terms, sum(positive) - sum(negative),
// each term L2-normalised first (so no term outweighs another by its length: text encoders do not
// all normalise; unit_vector, so that any finite term has its direction) and the result normalised
// (similarities stay cosines). Throws Error without a positive term, on mixed dimensions, zero or
// non-finite terms, or terms that cancel out.
Eigen::VectorXf composite_query(const std::vector<Eigen::VectorXf>& positive,
                                const std::vector<Eigen::VectorXf>& negative);

}  // namespace slamvdb
