// Query set files: the JSON format and the authors' folder of CSV files.
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/query/query_set.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kFormat = "slamvdb-query-set";
constexpr int kVersion = 1;

std::string read_text(const fs::path& file, std::string_view what) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw Error(fmt::format("cannot read {} {}", what, file.string()));
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Through the one output writer: an interrupted save never leaves half a file.
void write_text(const fs::path& file, const std::string& text) { write_output_file(file, text); }

json provenance_json(const QueryProvenance& p) {
  json j = json::object();
  if (!p.method.empty()) j["method"] = p.method;
  if (p.epochs) j["epochs"] = *p.epochs;
  if (p.learning_rate) j["learning_rate"] = *p.learning_rate;
  if (p.temperature) j["temperature"] = *p.temperature;
  if (p.seed) j["seed"] = *p.seed;
  if (p.accuracy) j["accuracy"] = *p.accuracy;
  if (!p.notes.empty()) j["notes"] = p.notes;
  return j;
}

QueryProvenance provenance_from(const json& j) {
  QueryProvenance p;
  if (j.contains("method")) p.method = j.at("method").get<std::string>();
  if (j.contains("epochs")) p.epochs = j.at("epochs").get<int>();
  if (j.contains("learning_rate")) p.learning_rate = j.at("learning_rate").get<double>();
  if (j.contains("temperature")) p.temperature = j.at("temperature").get<double>();
  if (j.contains("seed")) p.seed = j.at("seed").get<uint64_t>();
  if (j.contains("accuracy")) p.accuracy = j.at("accuracy").get<double>();
  if (j.contains("notes")) p.notes = j.at("notes").get<std::map<std::string, std::string>>();
  return p;
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// One line of comma-separated floats; errors give file:line:column.
std::vector<float> parse_csv_vector(const fs::path& file) {
  const std::string text = read_text(file, "query CSV file");
  std::vector<float> values;
  int line = 1;
  std::size_t line_start = 0, i = 0;
  const auto where = [&](std::size_t at) { return fmt::format("{}:{}:{}", file.string(), line, at - line_start + 1); };
  const auto skip_blanks = [&] {
    while (i < text.size() && (text[i] == ' ' || text[i] == '\t' || text[i] == '\r')) ++i;
  };
  while (true) {
    skip_blanks();
    if (i < text.size() && text[i] == '+') ++i;  // from_chars takes no '+'
    float v = 0.f;
    const auto [end, ec] = std::from_chars(text.data() + i, text.data() + text.size(), v);
    if (ec != std::errc() || !std::isfinite(v)) {
      const std::size_t stop = text.find_first_of(",\n", i);
      throw Error(fmt::format("{}: expected a finite number, got '{}'", where(i),
                              text.substr(i, std::min<std::size_t>(stop, text.size()) - i)));
    }
    values.push_back(v);
    i = static_cast<std::size_t>(end - text.data());
    skip_blanks();
    if (i < text.size() && text[i] == ',') {
      ++i;
      continue;
    }
    break;
  }
  // After the one line: only blank lines.
  for (; i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      line_start = i + 1;
    } else if (!std::isspace(static_cast<unsigned char>(text[i]))) {
      throw Error(fmt::format("{}: unexpected '{}' (one line of comma-separated numbers per class file)", where(i),
                              text[i]));
    }
  }
  return values;
}

}  // namespace

void save_query_set(const fs::path& file, const QuerySet& q) {
  q.validate(file.string());
  json classes = json::array();
  for (int k = 0; k < q.size(); ++k) {
    json c = {{"name", q.names[k]}, {"void", q.is_void(k)}};
    if (!q.colours.empty()) c["rgb"] = q.colours[k];
    // float -> double is exact, and the JSON writer prints doubles so that they read back exactly.
    std::vector<double> v(q.vectors.row(k).data(), q.vectors.row(k).data() + q.dim());
    c["vector"] = std::move(v);
    classes.push_back(std::move(c));
  }
  const json doc = {{"format", kFormat},     {"version", kVersion}, {"model_id", q.model_id},
                    {"dim", q.dim()},        {"classes", classes},  {"provenance", provenance_json(q.provenance)}};
  write_text(file, doc.dump(1) + "\n");
}

QuerySet load_query_set(const fs::path& file) {
  const std::string where = file.string();
  const std::string text = read_text(file, "query set file");
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    throw Error(fmt::format("{} is not a JSON query set (byte {}: {})", where, e.byte, e.what()));
  } catch (const json::exception& e) {
    // Not only parse_error: a number beyond double's range is an out_of_range (406) thrown by the
    // parser itself (found by fuzz_query_set).
    throw Error(fmt::format("{} is not a JSON query set ({})", where, e.what()));
  }
  if (!doc.is_object() || !doc.contains("format") || !doc["format"].is_string() || doc["format"] != kFormat)
    throw Error(fmt::format("{} is not a slamvdb query set (no \"format\": \"{}\")", where, kFormat));
  QuerySet q;
  try {
    const int version = doc.at("version").get<int>();
    if (version > kVersion || version < 1)
      throw Error(fmt::format("{} has query set format version {}; this slamvdb reads version {}", where, version,
                              kVersion));
    q.model_id = doc.at("model_id").get<std::string>();
    const int dim = doc.at("dim").get<int>();
    const json& classes = doc.at("classes");
    if (dim < 1 || !classes.is_array() || classes.empty())
      throw Error(fmt::format("{}: needs dim >= 1 and a non-empty 'classes' list", where));
    q.vectors.resize(static_cast<Eigen::Index>(classes.size()), dim);
    for (std::size_t k = 0; k < classes.size(); ++k) {
      const json& c = classes[k];
      q.names.push_back(c.at("name").get<std::string>());
      const auto v = c.at("vector").get<std::vector<double>>();
      if (static_cast<int>(v.size()) != dim)
        throw Error(fmt::format("{}: class '{}' has a {}-d vector, the file says dim {}", where, q.names.back(),
                                v.size(), dim));
      for (int d = 0; d < dim; ++d) q.vectors(static_cast<Eigen::Index>(k), d) = static_cast<float>(v[d]);
      if (c.contains("rgb")) {
        const auto rgb = c.at("rgb").get<std::vector<int>>();
        if (rgb.size() != 3 || std::any_of(rgb.begin(), rgb.end(), [](int v) { return v < 0 || v > 255; }))
          throw Error(fmt::format("{}: class '{}' rgb must be three values 0..255", where, q.names.back()));
        q.colours.push_back({static_cast<uint8_t>(rgb[0]), static_cast<uint8_t>(rgb[1]), static_cast<uint8_t>(rgb[2])});
      }
      if (c.value("void", false)) q.void_classes.push_back(static_cast<int>(k));
    }
    if (!q.colours.empty() && q.colours.size() != classes.size())
      throw Error(fmt::format("{}: some classes have an 'rgb' colour and some do not", where));
    if (doc.contains("provenance")) q.provenance = provenance_from(doc.at("provenance"));
  } catch (const json::exception& e) {
    throw Error(fmt::format("{}: malformed query set: {}", where, e.what()));
  }
  q.validate(where);
  return q;
}

QuerySet import_query_csv_dir(const fs::path& dir, std::string model_id, const Ontology* ontology) {
  if (!fs::is_directory(dir)) throw Error(fmt::format("query CSV folder {} is not a directory", dir.string()));
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file() && lower(entry.path().extension().string()) == ".csv") files.push_back(entry.path());
  if (files.empty()) throw Error(fmt::format("no .csv files in {}", dir.string()));
  std::sort(files.begin(), files.end());

  if (ontology) {  // ontology order; every class one file, every file one class
    std::vector<fs::path> ordered;
    std::vector<std::string> missing;
    for (const auto& c : ontology->classes()) {
      const auto it = std::find_if(files.begin(), files.end(),
                                   [&](const fs::path& f) { return lower(f.stem().string()) == lower(c.name); });
      if (it == files.end()) missing.push_back(c.name + ".csv");
      else ordered.push_back(*it);
    }
    if (!missing.empty())
      throw Error(fmt::format("{}: no file for ontology '{}' classes: {}", dir.string(), ontology->name(),
                              fmt::join(missing, ", ")));
    for (const auto& f : files)
      if (std::find(ordered.begin(), ordered.end(), f) == ordered.end())
        throw Error(fmt::format("{}: '{}' is no class of ontology '{}' (classes: {})", dir.string(),
                                f.filename().string(), ontology->name(), fmt::join(ontology->class_names(), ", ")));
    files = std::move(ordered);
  }

  QuerySet q;
  q.model_id = std::move(model_id);
  std::vector<std::vector<float>> rows;
  for (const auto& f : files) {
    rows.push_back(parse_csv_vector(f));
    if (rows.back().size() != rows.front().size())
      throw Error(fmt::format("{} has {} values but {} has {}: every class needs a vector of the same dimension",
                              f.string(), rows.back().size(), files.front().string(), rows.front().size()));
    q.names.push_back(f.stem().string());
  }
  q.vectors.resize(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(rows.front().size()));
  for (std::size_t k = 0; k < rows.size(); ++k)
    q.vectors.row(static_cast<Eigen::Index>(k)) =
        Eigen::Map<const Eigen::RowVectorXf>(rows[k].data(), static_cast<Eigen::Index>(rows[k].size()));
  if (ontology) {
    q.names = ontology->class_names();
    for (const auto& c : ontology->classes()) q.colours.push_back(c.rgb);
    q.void_classes = ontology->void_classes();
  }
  q.provenance.method = "csv-import";
  q.provenance.notes["source"] = dir.string();
  q.validate(dir.string());
  return q;
}

void export_query_csv_dir(const QuerySet& q, const fs::path& dir) {
  q.validate(dir.string());
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw Error(fmt::format("cannot create {}: {}", dir.string(), ec.message()));
  for (const auto& name : q.names)
    if (name.find_first_of("/\\") != std::string::npos || name.front() == '.')
      throw Error(fmt::format("class name '{}' cannot be a CSV file name", name));
  for (int k = 0; k < q.size(); ++k) {
    const float* v = q.vectors.row(k).data();
    write_text(dir / (q.names[k] + ".csv"), fmt::format("{:.9g}\n", fmt::join(v, v + q.dim(), ",")));
  }
}

}  // namespace slamvdb
