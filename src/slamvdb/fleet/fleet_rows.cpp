#include "slamvdb/fleet/fleet_rows.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/store/map_rows.hpp"

namespace slamvdb::fleet {
namespace {

// The elements of "{a,b,...}", each a whole finite number (from_chars: no locale, no exceptions).
template <class T>
std::vector<T> parse_array(std::string_view text, const std::string& what) {
  if (text.size() < 2 || text.front() != '{' || text.back() != '}')
    throw Error(fmt::format("{}: not an array ('{}')", what, text.substr(0, 80)));
  std::vector<T> out;
  const std::string_view body = text.substr(1, text.size() - 2);
  if (body.empty()) return out;
  for (std::size_t start = 0;;) {
    const std::size_t comma = std::min(body.find(',', start), body.size());
    const std::string_view item = body.substr(start, comma - start);
    T v{};
    const auto [end, ec] = std::from_chars(item.data(), item.data() + item.size(), v);
    if (ec != std::errc() || end != item.data() + item.size() || !std::isfinite(v))
      throw Error(fmt::format("{}: element {} ('{}') is not a finite number", what, out.size() + 1, item.substr(0, 40)));
    out.push_back(v);
    if (comma == body.size()) return out;
    start = comma + 1;
  }
}

}  // namespace

Pose parse_pose_array(std::string_view text, const std::string& what) {
  const std::vector<double> v = parse_array<double>(text, what);
  if (v.size() != 16) throw Error(fmt::format("{}: {} entries, expected 16", what, v.size()));
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<std::size_t>(4 * r + c)];
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if (!m.allFinite() || !((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() <= 1e-6) ||
      !(m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).isZero(1e-12))
    throw Error(fmt::format("{} is not a rigid transform", what));
  Pose T;
  T.matrix() = m;
  return T;
}

std::vector<float> parse_real_array(std::string_view text, const std::string& what) {
  return parse_array<float>(text, what);
}

std::map<std::string, std::string> parse_fleet_entries(std::string_view json, const std::string& what) {
  const nlohmann::json entries = nlohmann::json::parse(json, nullptr, /*allow_exceptions=*/false);
  if (!entries.is_object()) throw Error(fmt::format("{}: the fleet's parameters are not a JSON object", what));
  std::map<std::string, std::string> out;
  for (const auto& [key, value] : entries.items()) {
    if (!value.is_string()) throw Error(fmt::format("{}: the fleet's parameter '{}' is not a string", what, key));
    out.emplace(key, value.get<std::string>());
  }
  return out;
}

FleetDefinition fleet_definition_of(std::string_view json, const std::string& what) {
  store::Meta meta;
  for (auto& [key, value] : parse_fleet_entries(json, what))
    if (value != "(absent)") meta.emplace(key, std::move(value));
  FleetDefinition d;
  try {
    d.params = store::parse_params(meta);
    d.info.model_id = store::meta_value(meta, "model_id");
    d.info.ontology = store::meta_value(meta, "ontology");
  } catch (const Error& e) {
    throw Error(fmt::format("{}: {}", what, e.what()));
  }
  return d;
}

}  // namespace slamvdb::fleet
