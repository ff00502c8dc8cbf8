#include "slamvdb/server/request_decoding.hpp"

#include "slamvdb/core/point_text.hpp"

#include <fmt/format.h>

#include <cmath>
#include <set>

namespace slamvdb {

namespace request_decoding_detail {

std::vector<std::string> string_list(const nlohmann::json& v, const std::string& field, const ServerLimits& limits) {
  std::vector<std::string> out;
  const auto add = [&](const nlohmann::json& s) {
    if (!s.is_string()) throw RequestError(400, field, fmt::format("'{}' holds a {}, not a string", field, s.type_name()));
    const auto& text = s.get_ref<const std::string&>();
    if (text.empty() || text.size() > limits.max_text_bytes)
      throw RequestError(400, field, fmt::format("'{}': a text of {} bytes (1..{} allowed)", field, text.size(),
                                                 limits.max_text_bytes));
    out.push_back(text);
  };
  if (v.is_array()) {
    for (const auto& s : v) add(s);
  } else {
    add(v);
  }
  return out;
}

Eigen::VectorXf one_vector(const nlohmann::json& v, const std::string& field, int dim) {
  if (!v.is_array() || static_cast<int>(v.size()) != dim)
    throw RequestError(400, field, fmt::format("'{}': a vector is an array of {} numbers (the map's dimension)", field, dim));
  Eigen::VectorXf out(dim);
  for (int i = 0; i < dim; ++i) {
    const auto& x = v[static_cast<std::size_t>(i)];
    if (!x.is_number()) throw RequestError(400, field, fmt::format("'{}'[{}] is not a number", field, i));
    out[i] = x.get<float>();
    if (!std::isfinite(out[i])) throw RequestError(400, field, fmt::format("'{}'[{}] is not a finite float", field, i));
  }
  return out;
}

std::vector<Eigen::VectorXf> vector_list(const nlohmann::json& v, const std::string& field, int dim) {
  if (v.is_array() && !v.empty() && v[0].is_array()) {
    std::vector<Eigen::VectorXf> out;
    for (const auto& e : v) out.push_back(one_vector(e, field, dim));
    return out;
  }
  return {one_vector(v, field, dim)};
}

// A JSON array of finite numbers (any count: make_region checks the count), else a RequestError.
std::vector<double> number_list(const nlohmann::json& v, const std::string& field) {
  if (!v.is_array() || v.size() > 6)
    throw RequestError(400, field, fmt::format("'{}' is an array of at most 6 numbers", field));
  std::vector<double> out;
  for (const auto& x : v) {
    if (!x.is_number()) throw RequestError(400, field, fmt::format("'{}' holds a {}, not a number", field, x.type_name()));
    out.push_back(x.get<double>());
  }
  return out;
}

QueryRegion region_of(const nlohmann::json& v) {
  if (!v.is_object())
    throw RequestError(400, "region", "'region' is an object: {\"bbox\": [xmin, ymin, zmin, xmax, ymax, zmax]} and/or "
                                      "{\"near\": [x, y] or [x, y, z], \"radius\": r}");
  for (const auto& [key, value] : v.items())
    if (key != "bbox" && key != "near" && key != "radius")
      throw RequestError(400, "region." + key, fmt::format("unknown field 'region.{}'", key));
  std::optional<std::vector<double>> bbox, near;
  std::optional<double> radius;
  if (v.contains("bbox")) bbox = number_list(v["bbox"], "region.bbox");
  if (v.contains("near")) near = number_list(v["near"], "region.near");
  if (v.contains("radius")) {
    if (!v["radius"].is_number()) throw RequestError(400, "region.radius", "'region.radius' is a number of metres > 0");
    radius = v["radius"].get<double>();
  }
  try {
    return make_region(bbox ? std::optional<std::span<const double>>(*bbox) : std::nullopt,
                       near ? std::optional<std::span<const double>>(*near) : std::nullopt, radius,
                       {"region.bbox", "region.near", "region.radius"});
  } catch (const RegionError& e) {
    throw RequestError(400, e.field(), e.what());
  }
}

// "image": one base64 string or an array of them, each decoded to its bytes.
std::vector<std::string> image_list(const nlohmann::json& v) {
  std::vector<std::string> out;
  const auto add = [&](const nlohmann::json& s, std::size_t i) {
    if (!s.is_string())
      throw RequestError(400, "image", fmt::format("'image'[{}] holds a {}, not a base64 string", i, s.type_name()));
    std::optional<std::string> bytes = decode_base64(s.get_ref<const std::string&>());
    if (!bytes) throw RequestError(400, "image", fmt::format("'image'[{}] is not base64 (RFC 4648, standard alphabet)", i));
    if (bytes->empty()) throw RequestError(400, "image", fmt::format("'image'[{}] is empty", i));
    out.push_back(std::move(*bytes));
  };
  if (v.is_array()) {
    for (std::size_t i = 0; i < v.size(); ++i) add(v[i], i);
  } else {
    add(v, 0);
  }
  return out;
}

}  // namespace request_decoding_detail

std::optional<std::string> decode_base64(std::string_view text) {
  if (text.rfind("data:", 0) == 0) {  // a data URL: what a browser's FileReader gives
    const auto comma = text.find(',');
    if (comma == std::string_view::npos || comma < 7 || text.substr(comma - 7, 7) != ";base64") return std::nullopt;
    text.remove_prefix(comma + 1);
  }
  std::size_t padding = 0;
  while (padding < 2 && !text.empty() && text.back() == '=') text.remove_suffix(1), ++padding;
  if (text.size() % 4 == 1 || (padding && (text.size() + padding) % 4 != 0)) return std::nullopt;
  const auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
  };
  std::string out;
  out.reserve(text.size() / 4 * 3 + 2);
  uint32_t bits = 0;
  int held = 0;
  for (const char c : text) {
    const int v = value(c);
    if (v < 0) return std::nullopt;
    bits = (bits << 6) | static_cast<uint32_t>(v);
    held += 6;
    if (held >= 8) {
      held -= 8;
      out.push_back(static_cast<char>((bits >> held) & 0xFF));
    }
  }
  // What is left of the last group must be zero bits (a canonical encoding).
  if ((bits & ((1u << held) - 1)) != 0) return std::nullopt;
  return out;
}

nlohmann::json error_json(const std::string& message, const std::string& field) {
  return {{"error", {{"message", message}, {"field", field.empty() ? nlohmann::json() : nlohmann::json(field)}}}};
}

nlohmann::json parse_json_object(std::string_view body, int max_depth) {
  bool too_deep = false;
  // The callback sees each value's depth while parsing; a value below max_depth is dropped (false)
  // and remembered, so a body of a million '[' builds nothing deep.
  const nlohmann::json::parser_callback_t limit_depth = [&](int depth, nlohmann::json::parse_event_t, nlohmann::json&) {
    if (depth > max_depth) too_deep = true;
    return depth <= max_depth;
  };
  nlohmann::json j = nlohmann::json::parse(body.begin(), body.end(), limit_depth, /*allow_exceptions=*/false);
  if (too_deep) throw RequestError(400, "", fmt::format("the JSON body nests deeper than {} levels", max_depth));
  if (j.is_discarded()) throw RequestError(400, "", "the body is not JSON (RFC 8259, UTF-8)");
  if (!j.is_object()) throw RequestError(400, "", "the body is not a JSON object");
  return j;
}

QueryRequest decode_query_request(std::string_view body, int dim, const ServerLimits& limits) {
  using namespace request_decoding_detail;
  const nlohmann::json j = parse_json_object(body);
  static const std::set<std::string> known = {"text",       "not",   "class",     "not_class", "vector",
                                              "not_vector", "top_k", "threshold", "exact", "region", "image"};
  for (const auto& [key, value] : j.items())
    if (!known.count(key)) throw RequestError(400, key, fmt::format("unknown field '{}'", key));
  QueryRequest r;
  if (j.contains("text")) r.terms.text = string_list(j["text"], "text", limits);
  if (j.contains("not")) r.terms.not_text = string_list(j["not"], "not", limits);
  if (j.contains("class")) r.terms.classes = string_list(j["class"], "class", limits);
  if (j.contains("not_class")) r.terms.not_classes = string_list(j["not_class"], "not_class", limits);
  if (j.contains("vector")) r.terms.vectors = vector_list(j["vector"], "vector", dim);
  if (j.contains("not_vector")) r.terms.not_vectors = vector_list(j["not_vector"], "not_vector", dim);
  if (j.contains("image")) r.images = image_list(j["image"]);
  const std::size_t terms = r.images.size() + r.terms.text.size() + r.terms.not_text.size() + r.terms.classes.size() +
                            r.terms.not_classes.size() + r.terms.vectors.size() + r.terms.not_vectors.size();
  if (terms > limits.max_terms)
    throw RequestError(400, "", fmt::format("{} query terms; at most {}", terms, limits.max_terms));
  if (!r.terms.has_positive() && r.images.empty())
    throw RequestError(400, "text", "give a positive term: text, class, vector or image ('not' terms only subtract)");
  if (j.contains("threshold")) {
    const auto& t = j["threshold"];
    if (!t.is_number() || !(t.get<double>() >= -1.0 && t.get<double>() <= 1.0))
      throw RequestError(400, "threshold", "'threshold' is a number in -1..1 (a cosine similarity)");
    r.search.threshold = t.get<float>();
  }
  if (j.contains("top_k")) {
    const auto& k = j["top_k"];
    if (!k.is_number_unsigned() || k.get<uint64_t>() > limits.max_top_k)
      throw RequestError(400, "top_k", fmt::format("'top_k' is an integer in 0..{}", limits.max_top_k));
    r.search.top_k = static_cast<std::size_t>(k.get<uint64_t>());
    if (r.search.top_k == 0) {
      if (!j.contains("threshold")) throw RequestError(400, "top_k", "'top_k' 0 (every cell) needs a 'threshold'");
      r.search.top_k = limits.max_top_k;
      r.top_k_capped = true;
    }
  }
  if (j.contains("exact")) {
    if (!j["exact"].is_boolean()) throw RequestError(400, "exact", "'exact' is true or false");
    r.exact = j["exact"].get<bool>();
  }
  if (j.contains("region")) r.search.region = region_of(j["region"]);
  return r;
}

AtRequest decode_at_request(std::string_view body, const ServerLimits& limits) {
  const nlohmann::json j = parse_json_object(body);
  for (const auto& [key, value] : j.items())
    if (key != "points" && key != "embedding") throw RequestError(400, key, fmt::format("unknown field '{}'", key));
  if (!j.contains("points")) throw RequestError(400, "points", "give 'points': an array of [x, y, z]");
  const auto& points = j["points"];
  if (!points.is_array() || points.empty() || points.size() > limits.max_points)
    throw RequestError(400, "points", fmt::format("'points' is an array of 1..{} points [x, y, z]", limits.max_points));
  AtRequest r;
  r.points.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    if (!p.is_array() || p.size() != 3 || !p[0].is_number() || !p[1].is_number() || !p[2].is_number())
      throw RequestError(400, "points", fmt::format("'points'[{}] is not [x, y, z] (three numbers)", i));
    const Vec3d v(p[0].get<double>(), p[1].get<double>(), p[2].get<double>());
    if (!v.allFinite()) throw RequestError(400, "points", fmt::format("'points'[{}] is not finite", i));
    r.points.push_back(v);
  }
  if (j.contains("embedding")) {
    if (!j["embedding"].is_boolean()) throw RequestError(400, "embedding", "'embedding' is true or false");
    r.embedding = j["embedding"].get<bool>();
  }
  return r;
}

QueryRegion decode_region_params(const RegionParams& params, const std::string& route) {
  if (!params.bbox && !params.near && !params.radius)  // a radius alone: make_region names near
    throw RequestError(400, "bbox", fmt::format("{} needs ?bbox=xmin,ymin,zmin,xmax,ymax,zmax or ?near=x,y[,z]&radius=r "
                                                "(world metres)", route));
  std::optional<std::vector<double>> box, near;
  std::optional<double> radius;
  try {
    if (params.bbox) box = parse_numbers(*params.bbox, "bbox", 6, 6, "xmin,ymin,zmin,xmax,ymax,zmax");
  } catch (const Error& e) {
    throw RequestError(400, "bbox", e.what());
  }
  try {
    if (params.near) near = parse_numbers(*params.near, "near", 2, 3, "x,y or x,y,z");
  } catch (const Error& e) {
    throw RequestError(400, "near", e.what());
  }
  try {
    if (params.radius) radius = parse_numbers(*params.radius, "radius", 1, 1, "metres > 0")[0];
  } catch (const Error& e) {
    throw RequestError(400, "radius", e.what());
  }
  try {
    return make_region(box ? std::optional<std::span<const double>>(*box) : std::nullopt,
                       near ? std::optional<std::span<const double>>(*near) : std::nullopt, radius);
  } catch (const RegionError& e) {
    throw RequestError(400, e.field(), e.what());
  }
}

float decode_confidence_param(const std::string& text, const std::string& field) {
  std::vector<double> c;
  try {
    c = parse_numbers(text, field, 1, 1, "a number 0..1");
  } catch (const Error& e) {
    throw RequestError(400, field, e.what());
  }
  if (!(c[0] >= 0 && c[0] <= 1)) throw RequestError(400, field, fmt::format("{} {} is not in 0..1", field, c[0]));
  return static_cast<float>(c[0]);
}

ClassesRequest decode_classes_request(const RegionParams& region, const std::optional<std::string>& min_confidence) {
  ClassesRequest r;
  r.region = decode_region_params(region, "GET /api/classes");
  if (min_confidence) r.min_confidence = decode_confidence_param(*min_confidence, "min_confidence");
  return r;
}

NavGridRequest decode_nav_grid_request(const NavGridParams& params) {
  NavGridRequest r;
  r.region = decode_region_params(params.region, "GET /api/nav-grid");
  // One finite number in [lo, hi] (lo excluded when `open_low`), 400 naming `field` otherwise.
  const auto number = [](const std::string& text, const char* field, double lo, double hi, bool open_low) {
    std::vector<double> v;
    try {
      v = parse_numbers(text, field, 1, 1, "a number");
    } catch (const Error& e) {
      throw RequestError(400, field, e.what());
    }
    if (!(open_low ? v[0] > lo : v[0] >= lo) || !(v[0] <= hi))
      throw RequestError(400, field, fmt::format("{} {} is not in {}{}..{}", field, v[0], open_low ? "(" : "", lo, hi));
    return v[0];
  };
  if (params.resolution) r.resolution = number(*params.resolution, "resolution", 0, 1e6, true);
  if (params.robot_height) r.robot_height = number(*params.robot_height, "robot_height", 0.1, 100, false);
  if (params.min_confidence) r.min_confidence = decode_confidence_param(*params.min_confidence, "min_confidence");
  if (params.format) {
    const std::string& f = *params.format;
    if (f == "json") r.format = NavGridRequest::Format::kJson;
    else if (f == "pgm") r.format = NavGridRequest::Format::kPgm;
    else if (f == "png") r.format = NavGridRequest::Format::kPng;
    else if (f == "yaml") r.format = NavGridRequest::Format::kYaml;
    else throw RequestError(400, "format", fmt::format("format '{}': json, pgm, png or yaml", f));
  }
  return r;
}

}  // namespace slamvdb
