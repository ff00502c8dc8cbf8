#include "slamvdb/query/class_summary.hpp"

#include <fmt/format.h>

namespace slamvdb {

std::string_view class_label(const ClassifiedCell& c, const QuerySet& queries, float min_confidence) {
  if (c.match.class_index == kNoClass) return {};
  return is_uncertain(c, min_confidence) ? std::string_view("uncertain")
                                         : std::string_view(queries.names[static_cast<std::size_t>(c.match.class_index)]);
}

const std::vector<std::string>& classified_columns() {
  static const std::vector<std::string> columns{"x", "y", "z", "class", "score", "margin", "count", "confidence"};
  return columns;
}

std::vector<std::string> classified_row(const ClassifiedCell& c, const QuerySet& queries, float min_confidence) {
  const Vec3d& p = c.position_world;
  return {fmt::format("{:.3f}", p.x()),           fmt::format("{:.3f}", p.y()),
          fmt::format("{:.3f}", p.z()),           std::string(class_label(c, queries, min_confidence)),
          fmt::format("{:.6f}", c.match.score),   fmt::format("{:.6f}", c.match.margin),
          fmt::format("{}", c.count),             fmt::format("{:.4f}", c.confidence)};
}

ClassSummary summarize_classes(std::span<const ClassifiedCell> cells, const QuerySet& queries, float min_confidence) {
  ClassSummary s;
  s.cells = cells.size();
  s.per_class.assign(static_cast<std::size_t>(queries.size()), 0);
  for (const ClassifiedCell& c : cells) {
    s.statistics_unknown += !c.stats.known();
    if (c.match.class_index == kNoClass) ++s.unclassified;
    else if (is_uncertain(c, min_confidence)) ++s.uncertain;
    else ++s.per_class[static_cast<std::size_t>(c.match.class_index)];
  }
  return s;
}

}  // namespace slamvdb
