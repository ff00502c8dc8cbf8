#pragma once
// A class ontology loaded from YAML: the dataset's fine label ids (id, name, colour) grouped into
// the classes that query vectors are trained for and maps are labelled with (name, colour,
// optional navigation cost), which of those are "void" (never a final answer: a voxel whose best
// class is void takes its second-best, paper section 6.3.2), and how void and unlabelled pixels are
// used in training. Shipped: data/ontology/rellis3d_coarse.yaml (the paper's terrain ontology, the
// default) and rellis3d_fine.yaml (every RELLIS-3D class its own class), both built into the binary.
//
// File format (see the shipped files):
//   name: rellis3d-coarse
//   void: [void]                # class names that take their second-best / are ignored when scoring
//   void_pixels: train          # train | ignore: are pixels of void classes training targets?
//   unlabelled_ids: []          # label ids meaning "not annotated": never trained, never scored
//   classes:                    # in query order
//     - {name: smooth, rgb: [170, 170, 170], cost: 1.0, prompt: "paved road"}   # cost, prompt optional
//   labels:                     # every label id that may occur in the data
//     - {id: 10, name: asphalt, rgb: [64, 64, 64], class: smooth}
// The ontology's, classes' and labels' names follow the rule of display_name_problem
// (core/text_escape.hpp): at most 64 bytes of UTF-8 without control characters.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {


struct OntologyClass {
  std::string name;
  Rgb8 rgb{};
  std::optional<double> cost;  // relative traversal cost per metre; +inf = not traversable
  std::string prompt;          // text embedded to initialise the class's query (default: the name)
  bool is_void = false;
};

struct OntologyLabel {
  uint16_t id = 0;
  std::string name;
  Rgb8 rgb{};
  int class_index = 0;  // into Ontology::classes()
};

// How pixels whose label belongs to a void class are used when training query vectors. The paper
// trains a Void query (Void = void + sky) so that the void -> second-best rule has something to
// fire on: kTrain. kIgnore leaves them out (then the void query keeps its initial value).
enum class VoidPixels { kTrain, kIgnore };

// What a label id means for one purpose. Ids the ontology does not list are kUnknown: callers
// report them as errors (a wrong ontology for the data must not pass silently).
class LabelMapping {
 public:
  static constexpr int kIgnore = -1;   // not annotated (or void, when void pixels are not trained)
  static constexpr int kUnknown = -2;  // not in the ontology
  explicit LabelMapping(std::vector<int16_t> table) : table_(std::move(table)) {}
  int operator()(uint32_t id) const { return id < table_.size() ? table_[id] : kUnknown; }

 private:
  std::vector<int16_t> table_;
};

class Ontology {
 public:
  // Throws Error naming the file (and line for bad entries).
  static Ontology load(const std::filesystem::path& file);
  // `source` names the text in error messages.
  static Ontology parse(std::string_view yaml, std::string_view source);
  // The shipped ontologies compiled in: "rellis3d-coarse", "rellis3d-fine".
  static Ontology builtin(std::string_view name);
  static std::vector<std::string> builtin_names();
  // A built-in name or a file path.
  static Ontology load_or_builtin(std::string_view name_or_path);

  const std::string& name() const { return name_; }
  const std::string& source() const { return source_; }  // file path or "built-in NAME"
  const std::vector<OntologyClass>& classes() const { return classes_; }
  const std::vector<OntologyLabel>& labels() const { return labels_; }
  int num_classes() const { return static_cast<int>(classes_.size()); }
  std::vector<std::string> class_names() const;
  std::optional<int> find_class(std::string_view name) const;
  const OntologyLabel* find_label(uint16_t id) const;
  std::vector<int> void_classes() const;  // indices, ascending
  bool is_void(int class_index) const { return classes_.at(class_index).is_void; }
  VoidPixels void_pixels() const { return void_pixels_; }
  const std::vector<uint16_t>& unlabelled_ids() const { return unlabelled_; }

  // Label id -> training target: the class index; kIgnore for unlabelled ids and, when void pixels
  // are not trained, for void labels.
  LabelMapping training_targets() const;
  // Label id -> ground-truth class for scoring: the class index (void classes included: the
  // ConfusionMatrix ignores them), kIgnore for unlabelled ids.
  LabelMapping ground_truth() const;

 private:
  static Ontology parse_checked(std::string_view yaml, std::string_view source);
  LabelMapping mapping(bool ignore_void) const;

  std::string name_, source_;
  std::vector<OntologyClass> classes_;
  std::vector<OntologyLabel> labels_;
  std::vector<uint16_t> unlabelled_;
  VoidPixels void_pixels_ = VoidPixels::kTrain;
};

}  // namespace slamvdb
