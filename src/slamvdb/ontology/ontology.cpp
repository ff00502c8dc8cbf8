#include "slamvdb/ontology/ontology.hpp"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <string_view>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"

namespace slamvdb {
namespace {

#include "slamvdb/ontology/builtin_ontologies.inc"  // kBuiltinOntologies: {name, yaml text} (generated)

// Every message names the source and, when known, the line: "rellis3d_coarse.yaml:12: ...".
class Reader {
 public:
  explicit Reader(std::string_view source) : source_(source) {}

  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const {
    const YAML::Mark mark = at.Mark();
    if (mark.is_null()) throw Error(fmt::format("{}: {}", source_, what));
    throw Error(fmt::format("{}:{}: {}", source_, mark.line + 1, what));
  }
  [[noreturn]] void fail(const std::string& what) const { throw Error(fmt::format("{}: {}", source_, what)); }

  void only_keys(const YAML::Node& map, std::initializer_list<std::string_view> keys, std::string_view what) const {
    if (!map.IsMap()) fail(map, fmt::format("{} must be a mapping", what));
    for (const auto& kv : map) {
      const std::string key = kv.first.as<std::string>();
      if (std::find(keys.begin(), keys.end(), key) == keys.end())
        fail(kv.first, fmt::format("unknown key '{}' in {} (expected one of: {})", key, what, fmt::join(keys, ", ")));
    }
  }
  YAML::Node required(const YAML::Node& map, const char* key, std::string_view what) const {
    const YAML::Node node = map[key];
    if (!node) fail(map, fmt::format("{} has no '{}'", what, key));
    return node;
  }
  std::string string(const YAML::Node& node, std::string_view what) const {
    if (!node.IsScalar()) fail(node, fmt::format("{} must be a string", what));
    std::string s = node.as<std::string>();
    if (s.empty()) fail(node, fmt::format("{} is empty", what));
    return s;
  }
  // A name people read in tables, legends and files (core/text_escape.hpp's rule).
  std::string name(const YAML::Node& node, std::string_view what) const {
    std::string s = string(node, what);
    if (const std::string problem = display_name_problem(s); !problem.empty())
      fail(node, fmt::format("{} '{}' {} ({})", what, escape_control(s, kMaxDisplayNameBytes), problem,
                             kDisplayNameRule));
    return s;
  }
  long long integer(const YAML::Node& node, std::string_view what, long long lo, long long hi) const {
    long long v = 0;
    if (!node.IsScalar() || !YAML::convert<long long>::decode(node, v))
      fail(node, fmt::format("{} must be an integer, got '{}'", what, node.IsScalar() ? node.Scalar() : "a list"));
    if (v < lo || v > hi) fail(node, fmt::format("{} {} is out of range [{}, {}]", what, v, lo, hi));
    return v;
  }
  Rgb8 rgb(const YAML::Node& node, std::string_view what) const {
    if (!node.IsSequence() || node.size() != 3) fail(node, fmt::format("{} must be [r, g, b]", what));
    Rgb8 c{};
    for (std::size_t i = 0; i < 3; ++i) c[i] = static_cast<uint8_t>(integer(node[i], fmt::format("{} channel", what), 0, 255));
    return c;
  }
  double number(const YAML::Node& node, std::string_view what) const {
    double v = 0;
    if (!node.IsScalar() || !YAML::convert<double>::decode(node, v) || std::isnan(v))
      fail(node, fmt::format("{} must be a number, got '{}'", what, node.IsScalar() ? node.Scalar() : "a list"));
    return v;
  }

 private:
  std::string source_;
};

}  // namespace

Ontology Ontology::parse(std::string_view yaml, std::string_view source) {
  // A value of the wrong YAML type anywhere is a bad ontology naming its source, never an
  // escaping yaml-cpp exception (found by fuzz_ontology).
  try {
    return parse_checked(yaml, source);
  } catch (const YAML::Exception& e) {
    throw Error(fmt::format("ontology {}: {}", source, e.what()));
  }
}

Ontology Ontology::parse_checked(std::string_view yaml, std::string_view source) {
  const Reader r(source);
  YAML::Node doc;
  try {
    doc = YAML::Load(std::string(yaml));
  } catch (const YAML::ParserException& e) {
    r.fail(fmt::format("line {}: not valid YAML: {}", e.mark.line + 1, e.msg));
  }
  if (!doc.IsMap()) r.fail("is not a YAML mapping with 'name', 'classes' and 'labels'");
  r.only_keys(doc, {"name", "void", "void_pixels", "unlabelled_ids", "classes", "labels"}, "the ontology");

  Ontology o;
  o.source_ = std::string(source);
  o.name_ = r.name(r.required(doc, "name", "the ontology"), "name");

  const YAML::Node classes = r.required(doc, "classes", "the ontology");
  if (!classes.IsSequence() || classes.size() == 0) r.fail(classes, "'classes' must be a non-empty list");
  if (classes.size() > 32767) r.fail(classes, "more than 32767 classes");
  for (const YAML::Node& c : classes) {
    r.only_keys(c, {"name", "rgb", "cost", "prompt"}, "a class");
    OntologyClass cls;
    cls.name = r.name(r.required(c, "name", "a class"), "class name");
    if (o.find_class(cls.name)) r.fail(c, fmt::format("duplicate class name '{}'", cls.name));
    cls.rgb = r.rgb(r.required(c, "rgb", "class '" + cls.name + "'"), "class '" + cls.name + "' rgb");
    if (c["cost"]) {
      cls.cost = r.number(c["cost"], "class '" + cls.name + "' cost");
      if (*cls.cost < 0) r.fail(c["cost"], fmt::format("class '{}' cost {} is negative", cls.name, *cls.cost));
    }
    cls.prompt = c["prompt"] ? r.string(c["prompt"], "class '" + cls.name + "' prompt") : cls.name;
    o.classes_.push_back(std::move(cls));
  }

  if (const YAML::Node v = doc["void"]) {
    if (!v.IsSequence()) r.fail(v, "'void' must be a list of class names, e.g. [void]");
    for (const YAML::Node& name : v) {
      const std::string n = r.string(name, "void class");
      const auto k = o.find_class(n);
      if (!k) r.fail(name, fmt::format("void class '{}' is not one of the classes", n));
      if (o.classes_[*k].is_void) r.fail(name, fmt::format("void class '{}' is listed twice", n));
      o.classes_[*k].is_void = true;
    }
    if (std::all_of(o.classes_.begin(), o.classes_.end(), [](const auto& c) { return c.is_void; }))
      r.fail(v, "every class is void: no class would be left to answer");
  }
  if (const YAML::Node p = doc["void_pixels"]) {
    const std::string s = r.string(p, "void_pixels");
    if (s == "train") o.void_pixels_ = VoidPixels::kTrain;
    else if (s == "ignore") o.void_pixels_ = VoidPixels::kIgnore;
    else r.fail(p, fmt::format("void_pixels must be 'train' or 'ignore', got '{}'", s));
  }
  if (const YAML::Node u = doc["unlabelled_ids"]) {
    if (!u.IsSequence()) r.fail(u, "'unlabelled_ids' must be a list of label ids");
    for (const YAML::Node& id : u) {
      const auto v = static_cast<uint16_t>(r.integer(id, "unlabelled id", 0, 65535));
      if (std::find(o.unlabelled_.begin(), o.unlabelled_.end(), v) != o.unlabelled_.end())
        r.fail(id, fmt::format("unlabelled id {} is listed twice", v));
      o.unlabelled_.push_back(v);
    }
  }

  const YAML::Node labels = r.required(doc, "labels", "the ontology");
  if (!labels.IsSequence() || labels.size() == 0) r.fail(labels, "'labels' must be a non-empty list");
  std::set<std::string> label_names;
  for (const YAML::Node& l : labels) {
    r.only_keys(l, {"id", "name", "rgb", "class"}, "a label");
    OntologyLabel label;
    label.id = static_cast<uint16_t>(r.integer(r.required(l, "id", "a label"), "label id", 0, 65535));
    if (o.find_label(label.id)) r.fail(l, fmt::format("duplicate label id {}", label.id));
    if (std::find(o.unlabelled_.begin(), o.unlabelled_.end(), label.id) != o.unlabelled_.end())
      r.fail(l, fmt::format("label id {} is also listed in unlabelled_ids", label.id));
    label.name = r.name(r.required(l, "name", "a label"), "label name");
    if (!label_names.insert(label.name).second) r.fail(l, fmt::format("duplicate label name '{}'", label.name));
    label.rgb = r.rgb(r.required(l, "rgb", "label '" + label.name + "'"), "label '" + label.name + "' rgb");
    const YAML::Node cls = r.required(l, "class", "label '" + label.name + "'");
    const std::string class_name = r.string(cls, "label class");
    const auto k = o.find_class(class_name);
    if (!k)
      r.fail(cls, fmt::format("label '{}' names unknown class '{}' (classes: {})", label.name, class_name,
                              fmt::join(o.class_names(), ", ")));
    label.class_index = *k;
    o.labels_.push_back(std::move(label));
  }
  for (int k = 0; k < o.num_classes(); ++k)
    if (std::none_of(o.labels_.begin(), o.labels_.end(), [k](const auto& l) { return l.class_index == k; }))
      r.fail(classes[k], fmt::format("class '{}' has no label: no pixel could ever train or test it",
                                     o.classes_[k].name));
  return o;
}

Ontology Ontology::load(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw Error(fmt::format("cannot read ontology file {}", file.string()));
  std::stringstream text;
  text << in.rdbuf();
  return parse(text.str(), file.string());
}

Ontology Ontology::builtin(std::string_view name) {
  for (const auto& [n, yaml] : kBuiltinOntologies)
    if (n == name) return parse(yaml, fmt::format("built-in ontology {}", n));
  throw Error(fmt::format("no built-in ontology '{}' (built in: {})", name, fmt::join(builtin_names(), ", ")));
}

std::vector<std::string> Ontology::builtin_names() {
  std::vector<std::string> names;
  for (const auto& entry : kBuiltinOntologies) names.emplace_back(entry.first);
  return names;
}

Ontology Ontology::load_or_builtin(std::string_view name_or_path) {
  for (const auto& entry : kBuiltinOntologies)
    if (entry.first == name_or_path) return builtin(name_or_path);
  if (!std::filesystem::exists(std::filesystem::path(name_or_path)))
    throw Error(fmt::format("ontology '{}' is neither a file nor a built-in ontology ({})", name_or_path,
                            fmt::join(builtin_names(), ", ")));
  return load(std::filesystem::path(name_or_path));
}

std::vector<std::string> Ontology::class_names() const {
  std::vector<std::string> names;
  for (const auto& c : classes_) names.push_back(c.name);
  return names;
}

std::optional<int> Ontology::find_class(std::string_view name) const {
  for (std::size_t k = 0; k < classes_.size(); ++k)
    if (classes_[k].name == name) return static_cast<int>(k);
  return std::nullopt;
}

const OntologyLabel* Ontology::find_label(uint16_t id) const {
  for (const auto& l : labels_)
    if (l.id == id) return &l;
  return nullptr;
}

std::vector<int> Ontology::void_classes() const {
  std::vector<int> v;
  for (int k = 0; k < num_classes(); ++k)
    if (classes_[k].is_void) v.push_back(k);
  return v;
}

LabelMapping Ontology::mapping(bool ignore_void) const {
  uint32_t max_id = 0;
  for (const auto& l : labels_) max_id = std::max<uint32_t>(max_id, l.id);
  for (uint16_t id : unlabelled_) max_id = std::max<uint32_t>(max_id, id);
  std::vector<int16_t> table(max_id + 1, LabelMapping::kUnknown);
  for (const auto& l : labels_)
    table[l.id] = static_cast<int16_t>(ignore_void && classes_[l.class_index].is_void ? LabelMapping::kIgnore
                                                                                       : l.class_index);
  for (uint16_t id : unlabelled_) table[id] = LabelMapping::kIgnore;
  return LabelMapping(std::move(table));
}

LabelMapping Ontology::training_targets() const { return mapping(void_pixels_ == VoidPixels::kIgnore); }
LabelMapping Ontology::ground_truth() const { return mapping(false); }

}  // namespace slamvdb
