// The meta table: parameters and info as text, numbers in their shortest exact form.
#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <iterator>

#include "slamvdb/store/map_rows.hpp"

namespace slamvdb::store {
namespace {

template <class Params, class F>  // Params = MapParams or const MapParams
void for_each_number(Params& p, F&& f) {
  f("voxel_size", p.occupancy.voxel_size);
  f("log_odds_hit", p.occupancy.log_odds_hit);
  f("log_odds_miss", p.occupancy.log_odds_miss);
  f("clamp_min", p.occupancy.clamp_min);
  f("clamp_max", p.occupancy.clamp_max);
  f("occupied_threshold", p.occupancy.occupied_threshold);
  f("min_point_range", p.occupancy.min_point_range);
  f("max_point_range", p.occupancy.max_point_range);
  f("max_clearing_range", p.occupancy.max_clearing_range);
  f("semantic_dim", p.semantic.dim);
  f("submap_length", p.submap_length);
  f("index_cell_size", p.index_cell_size);
}

// Absent from version-1 files; their defaults describe what a version-1 map is.
bool optional_key(std::string_view key) { return key == "submap_length" || key == "index_cell_size"; }

template <class T>
T parse_number(const Meta& meta, const std::string& key) {
  const std::string& text = meta_value(meta, key);
  T v{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size())
    throw Error(fmt::format("meta entry '{}' = '{}' is not a number", key, text));
  if constexpr (std::is_floating_point_v<T>)
    if (!std::isfinite(v)) throw Error(fmt::format("meta entry '{}' = '{}' is not finite", key, text));
  return v;
}

// "dim lo0 lo1 lo2 hi0 hi1 hi2 mean[dim] axis0[dim] axis1[dim] axis2[dim]", shortest exact floats.
std::string format_colour_basis(const ColourBasis& b) {
  std::string text = std::to_string(b.dim());
  const auto add = [&](float v) { fmt::format_to(std::back_inserter(text), " {}", v); };
  for (int c = 0; c < 3; ++c) add(b.lo[c]);
  for (int c = 0; c < 3; ++c) add(b.hi[c]);
  for (int d = 0; d < b.dim(); ++d) add(b.mean[d]);
  for (int c = 0; c < 3; ++c)
    for (int d = 0; d < b.dim(); ++d) add(b.components(c, d));
  return text;
}

ColourBasis parse_colour_basis(const std::string& text, int map_dim) {
  const char* p = text.data();
  const char* const end = p + text.size();
  const auto next = [&](auto& v) {
    while (p < end && *p == ' ') ++p;
    const auto [q, ec] = std::from_chars(p, end, v);
    if (ec != std::errc()) throw Error("meta entry 'colour_basis' is not a list of numbers");
    p = q;
  };
  int dim = 0;
  next(dim);
  if (dim != map_dim)
    throw Error(fmt::format("meta entry 'colour_basis' is for {}-d embeddings, the map's are {}-d", dim, map_dim));
  ColourBasis b;
  b.mean.resize(dim);
  b.components.resize(3, dim);
  for (int c = 0; c < 3; ++c) next(b.lo[c]);
  for (int c = 0; c < 3; ++c) next(b.hi[c]);
  for (int d = 0; d < dim; ++d) next(b.mean[d]);
  for (int c = 0; c < 3; ++c)
    for (int d = 0; d < dim; ++d) next(b.components(c, d));
  if (p != end) throw Error("meta entry 'colour_basis' has more numbers than its dimension");
  try {
    b.validate(map_dim);
  } catch (const Error& e) {
    throw Error(fmt::format("meta entry 'colour_basis': {}", e.what()));
  }
  return b;
}

}  // namespace

Meta map_meta(const MapParams& params, const MapInfo& info) {
  Meta meta;
  for_each_number(params, [&](const char* key, const auto& v) { meta[key] = fmt::format("{}", v); });
  meta["semantic_precision"] = std::string(to_string(params.semantic.precision));
  if (params.semantic.single_view) meta.emplace("semantic_single_view", std::string(1, '1'));
  meta["format_version"] = std::to_string(kMapFormatVersion);
  meta["model_id"] = info.model_id;
  meta["ontology"] = info.ontology;
  meta["source"] = info.source;
  if (!info.config.empty()) meta["config"] = info.config;
  if (info.colour_basis) meta["colour_basis"] = format_colour_basis(*info.colour_basis);
  meta["fusion"] = info.fusion;
  if (!info.features.empty()) meta["features"] = info.features;
  return meta;
}

const std::string& meta_value(const Meta& meta, const std::string& key) {
  const auto it = meta.find(key);
  if (it == meta.end()) throw Error(fmt::format("meta entry '{}' is missing", key));
  return it->second;
}

MapParams parse_params(const Meta& meta) {
  MapParams params;
  params.submap_length = 0;  // a version-1 file holds one submap
  for_each_number(params, [&](const char* key, auto& v) {
    if (optional_key(key) && !meta.contains(key)) return;
    v = parse_number<std::decay_t<decltype(v)>>(meta, key);
  });
  params.semantic.precision = precision_from_string(meta_value(meta, "semantic_precision"));
  if (const auto single = meta.find("semantic_single_view"); single != meta.end()) {  // absent before format 3
    if (single->second != "0" && single->second != "1")
      throw Error(fmt::format("meta entry 'semantic_single_view' = '{}' is neither 0 nor 1", single->second));
    params.semantic.single_view = single->second == "1";
  }
  // Sanity beyond the parameters' own rules: values no map of ours can have.
  const double vs = params.occupancy.voxel_size;
  if (!(vs >= 1e-3 && vs <= 1e3)) throw Error(fmt::format("voxel size {} m is outside 0.001..1000", vs));
  if (params.semantic.dim < 1 || params.semantic.dim > 16384)
    throw Error(fmt::format("embedding dimension {} is outside 1..16384", params.semantic.dim));
  const OccupancyParams& o = params.occupancy;
  for (const float v : {o.log_odds_hit, o.log_odds_miss, o.clamp_min, o.clamp_max, o.occupied_threshold})
    if (!std::isfinite(v) || std::abs(v) > 100) throw Error(fmt::format("log-odds parameter {} is out of range", v));
  params.validate();
  return params;
}

MapInfo parse_info(const Meta& meta, int dim) {
  const auto config = meta.find("config");  // maps before the effective configuration was recorded lack it
  MapInfo info;
  info.model_id = meta_value(meta, "model_id");
  info.ontology = meta_value(meta, "ontology");
  info.source = meta_value(meta, "source");
  if (config != meta.end()) info.config = config->second;
  if (const auto basis = meta.find("colour_basis"); basis != meta.end())  // absent before bases were saved
    info.colour_basis = parse_colour_basis(basis->second, dim);
  if (const auto fusion = meta.find("fusion"); fusion != meta.end()) {  // absent before format 3: the paper's rule
    if (std::find(kFusionRuleNames.begin(), kFusionRuleNames.end(), fusion->second) == kFusionRuleNames.end())
      throw Error(fmt::format("meta entry 'fusion' = '{}' is not paper, quality or single-view", fusion->second));
    info.fusion = fusion->second;
  }
  if (const auto features = meta.find("features"); features != meta.end()) info.features = features->second;
  return info;
}

void write_meta(Database& db, const Meta& meta) {
  Statement insert(db, "INSERT OR REPLACE INTO meta(key, value, crc) VALUES(?, ?, ?)");
  for (const auto& [key, value] : meta)
    insert.bind(1, key).bind(2, value).bind(3, Crc().add(key.data(), key.size() + 1).add(value.data(), value.size()).value())
        .insert();
}

Meta read_meta(Database& db) {
  Meta meta;
  Statement rows(db, "SELECT key, value, crc FROM meta");
  while (rows.step()) {
    const std::string key = rows.text(0), value = rows.text(1);
    if (Crc().add(key.data(), key.size() + 1).add(value.data(), value.size()).value() != rows.int64(2))
      throw Error(fmt::format("CRC mismatch in meta entry '{}': the file is corrupt", key));
    meta[key] = value;
  }
  return meta;
}

}  // namespace slamvdb::store
