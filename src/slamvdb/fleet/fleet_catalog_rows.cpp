#include "slamvdb/fleet/fleet_catalog_rows.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_rows.hpp"

namespace slamvdb::fleet {
namespace {

// The columns of one row, read by index with the row's name in every message.
class RowReader {
 public:
  RowReader(const TextRow& row, std::size_t columns, std::string what) : row_(row), what_(std::move(what)) {
    if (row.size() != columns) throw Error(fmt::format("{}: {} columns, expected {}", what_, row.size(), columns));
  }
  const std::string& what() const { return what_; }
  bool is_null(std::size_t i) const { return !row_[i]; }
  std::string_view text(std::size_t i, const char* column) const {
    if (!row_[i]) throw Error(fmt::format("{}: {} is NULL", what_, column));
    return *row_[i];
  }
  template <class T>
  T integer(std::size_t i, const char* column) const {
    const std::string_view t = text(i, column);
    T v{};
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size() || t.empty())
      throw Error(fmt::format("{}: {} ('{}') is not an integer in range", what_, column, t.substr(0, 40)));
    return v;
  }
  double real(std::size_t i, const char* column) const {
    const std::string_view t = text(i, column);
    double v = 0;
    const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || end != t.data() + t.size() || !std::isfinite(v))
      throw Error(fmt::format("{}: {} ('{}') is not a finite number", what_, column, t.substr(0, 40)));
    return v;
  }
  // Both ends or none (either NULL: no time range, as a map file's submaps without stamps).
  std::optional<std::pair<double, double>> time_range(std::size_t begin, std::size_t end) const {
    if (is_null(begin) || is_null(end)) return std::nullopt;
    return std::pair{real(begin, "time_begin"), real(end, "time_end")};
  }
  // Columns first..first+5: x_min, y_min, z_min, x_max, y_max, z_max; min <= max on every axis.
  Eigen::AlignedBox3d box(std::size_t first) const {
    const Vec3d lo(real(first, "x_min"), real(first + 1, "y_min"), real(first + 2, "z_min"));
    const Vec3d hi(real(first + 3, "x_max"), real(first + 4, "y_max"), real(first + 5, "z_max"));
    if (!(lo.array() <= hi.array()).all()) throw Error(fmt::format("{}: its box has a minimum above its maximum", what_));
    return {lo, hi};
  }

 private:
  const TextRow& row_;
  std::string what_;
};

CatalogSession session_of(const TextRow& row, std::size_t index) {
  const RowReader r(row, kCatalogSessionColumns, fmt::format("catalog session row {}", index + 1));
  CatalogSession s;
  s.id = r.integer<int64_t>(0, "id");
  s.name = r.text(1, "name");
  s.robot = r.text(2, "robot");
  s.source = r.text(3, "source");
  s.time_range = r.time_range(4, 5);
  s.T_fleet_session = parse_pose_array(r.text(6, "t_fleet_session"), fmt::format("session '{}' frame", s.name));
  return s;
}

CatalogSubmap submap_of(const RowReader& r, const CatalogSession& session) {
  CatalogSubmap m;
  m.session = session.name;
  m.id = r.integer<int>(1, "submap");
  m.T_fleet_submap = session.T_fleet_session *
                     parse_pose_array(r.text(2, "t_world_submap"), fmt::format("session '{}' submap {} anchor", m.session, m.id));
  m.time_range = r.time_range(3, 4);
  m.path_length = r.real(5, "path_length");
  m.blocks = r.integer<std::size_t>(6, "blocks");
  m.known_voxels = r.integer<std::size_t>(7, "known_voxels");
  m.occupied_voxels = r.integer<std::size_t>(8, "occupied_voxels");
  m.semantic_voxels = r.integer<std::size_t>(9, "semantic_voxels");
  m.revision = r.integer<int>(10, "revision");
  m.bounds_fleet = r.box(11);
  return m;
}

}  // namespace

FleetCatalog catalog_of(const std::vector<TextRow>& sessions, const std::vector<TextRow>& submaps) {
  FleetCatalog out;
  std::map<int64_t, std::size_t> session_at;
  for (std::size_t i = 0; i < sessions.size(); ++i) {
    CatalogSession s = session_of(sessions[i], i);
    if (!session_at.emplace(s.id, out.sessions.size()).second)
      throw Error(fmt::format("catalog session row {}: session id {} given twice", i + 1, s.id));
    out.sessions.push_back(std::move(s));
  }
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    const RowReader r(submaps[i], kCatalogSubmapColumns, fmt::format("catalog submap row {}", i + 1));
    const auto at = session_at.find(r.integer<int64_t>(0, "session"));
    if (at == session_at.end()) {
      ++out.submaps_without_session;
      continue;
    }
    CatalogSession& session = out.sessions[at->second];
    out.submaps.push_back(submap_of(r, session));
    ++session.submaps;
  }
  return out;
}

RegionSubmap region_submap_of(const TextRow& row) {
  const RowReader r(row, kRegionSubmapColumns, "region catalog row");
  RegionSubmap s;
  s.key = {r.integer<int64_t>(0, "session"), r.integer<int>(1, "submap")};
  s.bounds_fleet = r.box(2);
  if (!r.is_null(9)) {
    const std::string what = fmt::format("submap {} of session {} embedding summary", s.key.second, s.key.first);
    EmbeddingCap cap{parse_real_array(r.text(8, "embedding_centroid"), what), r.real(9, "embedding_radius")};
    const Eigen::Map<const Eigen::VectorXf> centroid(cap.centroid.data(), static_cast<Eigen::Index>(cap.centroid.size()));
    if (!(centroid.norm() > 0) || !(cap.radius >= 0))
      throw Error(fmt::format("{}: a centroid of no length or a negative radius", what));
    s.cap = std::move(cap);
  }
  s.semantic_voxels = r.integer<std::size_t>(10, "semantic_voxels");
  return s;
}

}  // namespace slamvdb::fleet
