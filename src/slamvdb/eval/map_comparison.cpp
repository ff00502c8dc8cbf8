#include "slamvdb/eval/map_comparison.hpp"

#include <algorithm>
#include <vector>

namespace slamvdb {
namespace {

std::size_t matched(const std::vector<IndexCellKey>& from, const std::vector<IndexCellKey>& in, int tolerance) {
  std::size_t n = 0;
  for (const IndexCellKey& c : from) {
    bool hit = false;
    for (int dx = -tolerance; dx <= tolerance && !hit; ++dx)
      for (int dy = -tolerance; dy <= tolerance && !hit; ++dy)
        for (int dz = -tolerance; dz <= tolerance && !hit; ++dz)
          hit = std::binary_search(in.begin(), in.end(), IndexCellKey(c.x() + dx, c.y() + dy, c.z() + dz));
    n += hit;
  }
  return n;
}

}  // namespace

OccupiedCells occupied_world_cells(const SemanticMap& m) {
  OccupiedCells cells;
  for (const WorldOccupancyCell& c : m.world_occupancy())
    if (c.log_odds >= m.params().occupancy.occupied_threshold) cells.push_back(c.cell);
  return cells;  // sorted by key
}

double occupied_iou(const SemanticMap& a, const SemanticMap& b, int tolerance) {
  return occupied_iou(occupied_world_cells(a), occupied_world_cells(b), tolerance);
}

double occupied_iou(const OccupiedCells& ca, const OccupiedCells& cb, int tolerance) {
  if (ca.empty() && cb.empty()) return 1.0;
  const double shared = 0.5 * static_cast<double>(matched(ca, cb, tolerance) + matched(cb, ca, tolerance));
  return shared / (static_cast<double>(ca.size() + cb.size()) - shared);
}

}  // namespace slamvdb
