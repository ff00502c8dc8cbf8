// The fleet catalog's row decoding (fleet/fleet_catalog_rows.hpp): the sessions and submaps rows
// that FleetDatabase::catalog (GET /api/info of `serve --db`) and region_catalog (every region
// question) turn into CatalogSession, CatalogSubmap and RegionSubmap, here without a database.
// The input is rows in COPY's text form: rows end with '\n', fields are split by '\t', "\N" is
// NULL. The first byte picks the decoder: even, catalog_of (the sessions' rows, a line "\.",
// the submaps' rows); odd, region_submap_of on each row. What is accepted must be usable as it is:
// finite rigid poses, finite boxes with min <= max, every submap under a session of the catalog,
// summaries with a centroid of some length.
#include <algorithm>
#include <cmath>
#include <optional>
#include <string_view>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_catalog_rows.hpp"

namespace {

using slamvdb::fleet::TextRow;

std::vector<TextRow> rows_of(std::string_view text) {
  std::vector<TextRow> rows;
  while (!text.empty()) {
    const std::size_t eol = std::min(text.find('\n'), text.size());
    std::string_view line = text.substr(0, eol);
    text.remove_prefix(std::min(eol + 1, text.size()));
    TextRow row;
    for (;;) {
      const std::size_t tab = std::min(line.find('\t'), line.size());
      const std::string_view field = line.substr(0, tab);
      row.push_back(field == "\\N" ? std::nullopt : std::optional<std::string_view>(field));
      if (tab == line.size()) break;
      line.remove_prefix(tab + 1);
    }
    rows.push_back(std::move(row));
  }
  return rows;
}

bool usable_box(const Eigen::AlignedBox3d& b) {
  return b.min().allFinite() && b.max().allFinite() && (b.min().array() <= b.max().array()).all();
}

bool rigid(const slamvdb::Pose& T) {
  const Eigen::Matrix3d R = T.linear();
  // A product of two rigid poses: orthonormal to the parsers' 1e-6 each, so 1e-5 together.
  return T.matrix().allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() <= 1e-5;
}

bool usable_time(const std::optional<std::pair<double, double>>& t) {
  return !t || (std::isfinite(t->first) && std::isfinite(t->second));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    if (data[0] % 2 == 0) {
      const std::size_t split = text.find("\\.\n");
      const std::string_view sessions = text.substr(0, split);
      const std::string_view submaps = split == std::string_view::npos ? std::string_view() : text.substr(split + 3);
      const slamvdb::fleet::FleetCatalog catalog =
          slamvdb::fleet::catalog_of(rows_of(sessions), rows_of(submaps));
      std::size_t counted = 0;
      for (const slamvdb::fleet::CatalogSession& s : catalog.sessions) {
        if (!rigid(s.T_fleet_session) || !usable_time(s.time_range)) __builtin_trap();
        counted += s.submaps;
      }
      if (counted != catalog.submaps.size()) __builtin_trap();
      for (const slamvdb::fleet::CatalogSubmap& m : catalog.submaps) {
        bool known = false;
        for (const slamvdb::fleet::CatalogSession& s : catalog.sessions) known = known || s.name == m.session;
        if (!known || !rigid(m.T_fleet_submap) || !usable_box(m.bounds_fleet) || !usable_time(m.time_range) ||
            !std::isfinite(m.path_length))
          __builtin_trap();
      }
    } else {
      for (const TextRow& row : rows_of(text)) {
        const slamvdb::fleet::RegionSubmap s = slamvdb::fleet::region_submap_of(row);
        if (!usable_box(s.bounds_fleet)) __builtin_trap();
        if (s.cap) {
          double norm = 0;
          for (const float v : s.cap->centroid) {
            if (!std::isfinite(v)) __builtin_trap();
            norm += double{v} * v;
          }
          if (!(norm > 0) || !(s.cap->radius >= 0) || !std::isfinite(s.cap->radius)) __builtin_trap();
        }
      }
    }
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
