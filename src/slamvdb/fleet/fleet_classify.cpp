#include "slamvdb/fleet/fleet_classify.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>

namespace slamvdb::fleet {
namespace {

// Whether a submap whose box is `b` can put an entry in a cell whose centre lies in `region`: an
// entry lies within half a cell of its cell's centre, so `b` grown by one cell must meet the shape.
bool can_meet(const Eigen::AlignedBox3d& b, const QueryRegion& region, double cell) {
  Eigen::AlignedBox3d grown = b;
  grown.min().array() -= cell;
  grown.max().array() += cell;
  if (region.box && !grown.intersects(*region.box)) return false;
  if (!region.near) return true;
  Vec3d gap = (grown.min() - region.near->centre).cwiseMax(region.near->centre - grown.max()).cwiseMax(0.0);
  if (region.near->horizontal) gap.z() = 0;
  return gap.norm() <= region.near->radius;
}

}  // namespace

FleetClassification classify_fleet_region(FleetDatabase& fleet, const QueryRegion& region, const QuerySet& queries,
                                          const FleetClassifyOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const FleetDefinition definition = fleet.definition();
  FleetClassification out;
  // The query set checked against the fleet's space even when the region is empty.
  classify_region(SemanticMap(definition.params, definition.info), queries, region, options.classify,
                  options.model_check);
  const double cell = definition.params.index_cell();
  const double side = cell * std::max(1.0, std::round(options.tile_side / cell));  // tile edges on cell edges:
  // a cell centre is never on one, so each cell is in exactly one tile
  const Eigen::AlignedBox3d bounds = region.bounds();
  const std::vector<RegionSubmap> submaps = fleet.region_catalog({bounds, options.sessions});
  out.submaps_in_region = submaps.size();

  // The tiles each kept submap can put entries in (within one cell), and the submaps of each tile.
  using Tile = std::pair<int64_t, int64_t>;
  const auto tile_of = [&](double v) { return static_cast<int64_t>(std::floor(v / side)); };
  std::map<Tile, std::vector<std::size_t>> tiles;
  std::set<std::size_t> read;
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    const RegionSubmap& s = submaps[i];
    if (s.semantic_voxels == 0 || !can_meet(s.bounds_fleet, region, cell)) continue;
    const Vec3d lo = s.bounds_fleet.min().array() - cell, hi = s.bounds_fleet.max().array() + cell;
    const Vec3d rlo = bounds.min(), rhi = bounds.max();  // only tiles that meet the region's bounds
    for (int64_t tx = tile_of(std::max(lo.x(), rlo.x())); tx <= tile_of(std::min(hi.x(), rhi.x())); ++tx)
      for (int64_t ty = tile_of(std::max(lo.y(), rlo.y())); ty <= tile_of(std::min(hi.y(), rhi.y())); ++ty)
        tiles[{tx, ty}].push_back(i);
    read.insert(i);
  }
  out.submaps_read = read.size();
  out.submaps_skipped = submaps.size() - read.size();
  out.tiles = tiles.size();

  for (const auto& [tile, members] : tiles) {
    QueryRegion part = region;  // the region's cells whose centre is in this tile
    const Eigen::AlignedBox3d tile_box(Vec3d(tile.first * side, tile.second * side, bounds.min().z()),
                                       Vec3d((tile.first + 1) * side, (tile.second + 1) * side, bounds.max().z()));
    part.box = region.box ? region.box->intersection(tile_box) : tile_box;
    if (part.box->isEmpty()) continue;
    PullRequest request{Eigen::AlignedBox3d(), options.sessions, std::vector<FleetSubmapKey>{}};
    for (const std::size_t i : members) {
      request.box_fleet.extend(submaps[i].bounds_fleet);
      request.only->push_back(submaps[i].key);
    }
    SemanticMap map(definition.params, definition.info);
    fleet.pull(request, [&](PulledSubmap&& s) { map.add_finished_submap(s.info, std::move(s.voxels)); });
    out.reads += members.size();
    out.peak_submaps_in_memory = std::max(out.peak_submaps_in_memory, members.size());
    std::vector<ClassifiedCell> cells = classify_region(map, queries, part, options.classify, options.model_check);
    out.cells.insert(out.cells.end(), cells.begin(), cells.end());
  }
  sort_by_cell(out.cells);
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace slamvdb::fleet
