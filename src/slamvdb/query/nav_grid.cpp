#include "slamvdb/query/nav_grid.hpp"

#include <fmt/format.h>

#include <absl/container/flat_hash_map.h>

#include <cmath>
#include <limits>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

struct Column {
  int ground_z = std::numeric_limits<int>::max();  // lowest occupied cell
  std::vector<int> occupied_z;
};

}  // namespace

std::optional<int8_t> default_terrain_cost(const std::string& name) {
  static const std::map<std::string, int8_t> kCosts = {{"smooth", 0},     {"rough", 30},   {"bumpy", 60},
                                                       {"obstacle", 100}, {"active", 100}, {"void", kUnknownCost}};
  const auto it = kCosts.find(name);
  if (it == kCosts.end()) return std::nullopt;
  return it->second;
}

std::vector<int8_t> nav_class_costs(const std::vector<std::string>& class_names,
                                    const std::vector<std::string>& overrides) {
  std::map<std::string, int> given;
  for (const std::string& item : overrides) {
    const auto eq = item.find('=');
    std::size_t used = 0;
    int cost = 0;
    bool ok = eq != std::string::npos && eq + 1 < item.size();
    if (ok) {
      try {
        cost = std::stoi(item.substr(eq + 1), &used);
      } catch (const std::exception&) {
        ok = false;
      }
    }
    if (!ok || used != item.size() - eq - 1 || cost < -1 || cost > 100)
      throw Error(fmt::format("'{}': expected CLASS=COST with COST in -1 (unknown) .. 100 (lethal)", item));
    given[item.substr(0, eq)] = cost;
  }
  std::vector<int8_t> costs;
  for (const std::string& name : class_names) {
    if (const auto it = given.find(name); it != given.end()) {
      costs.push_back(static_cast<int8_t>(it->second));
      given.erase(it);
    } else if (const auto d = default_terrain_cost(name)) {
      costs.push_back(*d);
    } else {
      throw Error(fmt::format("class '{}' has no default navigation cost: give --cost {}=COST", name, name));
    }
  }
  if (!given.empty()) throw Error(fmt::format("the query set has no class '{}' (--cost)", given.begin()->first));
  return costs;
}

std::vector<Eigen::Vector2d> submap_path(const SemanticMap& map) {
  std::vector<Eigen::Vector2d> path;
  for (const SubmapInfo& s : map.submaps()) path.push_back(s.T_world_submap.translation().head<2>());
  return path;
}

int nav_grid_factor(double resolution, double cell) {
  if (resolution == 0) return 1;
  const double k = resolution / cell;
  const double whole = std::round(k);
  if (!std::isfinite(k) || whole < 1 || whole > 64 || std::abs(k - whole) > 1e-6 * whole)
    throw Error(fmt::format("grid resolution {} m is not a whole multiple (1..64) of the map's cell of {} m", resolution,
                            cell));
  return static_cast<int>(whole);
}

namespace {

// Each cell of the result the worst of its k x k cells of `fine` (NavGridOptions::resolution).
NavGrid coarsened_nav_grid(const NavGrid& fine, int k) {
  NavGrid g;
  g.resolution = fine.resolution * k;
  g.origin = fine.origin;
  g.width = (fine.width + k - 1) / k;
  g.height = (fine.height + k - 1) / k;
  const std::size_t n = static_cast<std::size_t>(g.width) * g.height;
  g.cost.assign(n, kUnknownCost);
  g.ground_class.assign(n, -1);
  g.obstacle.assign(n, 0);
  g.uncertain.assign(n, 0);
  for (int row = 0; row < fine.height; ++row)
    for (int col = 0; col < fine.width; ++col) {
      const std::size_t f = fine.index(col, row), c = g.index(col / k, row / k);
      g.obstacle[c] |= fine.obstacle[f];
      g.uncertain[c] |= fine.uncertain[f];
      if (fine.cost[f] != kUnknownCost && (g.cost[c] == kUnknownCost || fine.cost[f] > g.cost[c])) {
        g.cost[c] = fine.cost[f];
        g.ground_class[c] = fine.ground_class[f];
      } else if (g.ground_class[c] < 0) {
        g.ground_class[c] = fine.ground_class[f];
      }
    }
  for (std::size_t c = 0; c < n; ++c)
    if (g.cost[c] != kUnknownCost) g.uncertain[c] = 0;  // a known cost was taken: not a guess
  return g;
}

}  // namespace

Eigen::Vector2i NavGrid::cell_of(double x, double y) const {
  return {static_cast<int>(std::floor((x - origin.x()) / resolution)),
          static_cast<int>(std::floor((y - origin.y()) / resolution))};
}

NavGrid build_nav_grid(const SemanticMap& map, const std::vector<ClassifiedCell>& cells, const NavGridOptions& options) {
  if (!(options.robot_height > 0) || !std::isfinite(options.robot_height))
    throw Error(fmt::format("robot height {} m must be a positive number", options.robot_height));
  const double res = map.params().index_cell();  // world occupancy and the index share this grid
  const float threshold = map.params().occupancy.occupied_threshold;
  absl::flat_hash_map<std::pair<int, int>, Column> columns;
  int x0 = std::numeric_limits<int>::max(), y0 = x0, x1 = std::numeric_limits<int>::min(), y1 = x1;
  for (const WorldOccupancyCell& c : map.world_occupancy()) {
    if (c.log_odds < threshold) continue;
    if (options.region && !options.region->contains(center_of_key(c.cell, res))) continue;
    Column& col = columns[{c.cell.x(), c.cell.y()}];
    col.ground_z = std::min(col.ground_z, c.cell.z());
    col.occupied_z.push_back(c.cell.z());
    x0 = std::min(x0, c.cell.x()), x1 = std::max(x1, c.cell.x());
    y0 = std::min(y0, c.cell.y()), y1 = std::max(y1, c.cell.y());
  }
  if (columns.empty())
    throw NavGridEmpty(options.region ? "the region holds no occupied cells to build a navigation grid from"
                                      : "the map has no occupied cells to build a navigation grid from");

  NavGrid grid;
  grid.resolution = res;
  grid.width = x1 - x0 + 1;
  grid.height = y1 - y0 + 1;
  grid.origin = {x0 * res, y0 * res};
  const std::size_t n = static_cast<std::size_t>(grid.width) * grid.height;
  grid.cost.assign(n, kUnknownCost);
  grid.ground_class.assign(n, -1);
  grid.obstacle.assign(n, 0);
  grid.uncertain.assign(n, 0);

  // The ground's class: the semantic cell at the ground, else the lowest one within a cell above
  // it (the camera may have seen the top of a ground voxel the LiDAR put one cell lower).
  absl::flat_hash_map<std::pair<int, int>, const ClassifiedCell*> ground_semantic;  // column -> its ground cell
  for (const ClassifiedCell& c : cells) {
    const auto it = columns.find({c.cell.x(), c.cell.y()});
    if (it == columns.end() || c.match.class_index == kNoClass) continue;
    const int dz = c.cell.z() - it->second.ground_z;
    if (dz < 0 || dz > 1) continue;
    auto [entry, inserted] = ground_semantic.try_emplace(it->first, &c);
    if (!inserted && c.cell.z() < entry->second->cell.z()) entry->second = &c;
  }

  const int clear_cells = static_cast<int>(std::ceil(options.robot_height / res));
  for (const auto& [xy, col] : columns) {
    const std::size_t i = grid.index(xy.first - x0, xy.second - y0);
    // An obstacle: occupied above the ground cell (more than one cell up, so a ground voxel and
    // the one above it on a slope do not block), within the robot's height.
    for (const int z : col.occupied_z) {
      const int above = z - col.ground_z;
      if (above >= 2 && above <= clear_cells) grid.obstacle[i] = 1;
    }
    if (const auto g = ground_semantic.find(xy); g != ground_semantic.end()) {
      const int k = g->second->match.class_index;
      if (k < 0 || static_cast<std::size_t>(k) >= options.class_cost.size())
        throw Error(fmt::format("no cost given for class {} of the navigation grid", k));
      grid.ground_class[i] = static_cast<int16_t>(k);
      if (is_uncertain(*g->second, options.min_confidence))
        grid.uncertain[i] = 1;  // cost stays unknown
      else
        grid.cost[i] = options.class_cost[static_cast<std::size_t>(k)];
    }
    if (grid.obstacle[i]) grid.cost[i] = kLethalCost;
  }
  const int k = nav_grid_factor(options.resolution, res);
  return k == 1 ? grid : coarsened_nav_grid(grid, k);
}

}  // namespace slamvdb
