#pragma once
// What `classify` says about classified cells, in one place for every caller (the CLI's table and
// CSV, GET /api/classes): the class written for a cell, a cell's row as the CSV writes it, and the
// count per class.
#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/query/map_query.hpp"

namespace slamvdb {

// The class name written for a cell: empty without a class, `uncertain` below min_confidence.
std::string_view class_label(const ClassifiedCell& c, const QuerySet& queries, float min_confidence);

// The columns of a classified cell's row: x,y,z,class,score,margin,count,confidence.
const std::vector<std::string>& classified_columns();
// A cell's row as `classify -o X.csv` writes it (cell centre in the world frame, 3 decimals; score
// and margin 6, confidence 4; the class is class_label's).
std::vector<std::string> classified_row(const ClassifiedCell& c, const QuerySet& queries, float min_confidence);

struct ClassSummary {
  std::size_t cells = 0;
  std::vector<std::size_t> per_class;  // one per class of the query set (certain cells only)
  std::size_t uncertain = 0;           // below min_confidence
  std::size_t unclassified = 0;        // no class: a zero embedding
  std::size_t statistics_unknown = 0;  // no observation statistics (a map before format 3)
  // Share of all cells, 0..100 (0 without cells).
  double percent(std::size_t n) const { return cells ? 100.0 * static_cast<double>(n) / static_cast<double>(cells) : 0.0; }
};
ClassSummary summarize_classes(std::span<const ClassifiedCell> cells, const QuerySet& queries, float min_confidence);

}  // namespace slamvdb
