#pragma once
// A 2D navigation grid from a classified map (paper section 6.3.2: terrain classes for planning):
// per world column, the ground (the lowest occupied cell) with its terrain class, and an obstacle
// wherever something occupied stands above the ground within the robot's height. Costs per class
// in the ROS costmap range: 0 free .. 100 lethal, -1 unknown. Pure: the writers (PGM / YAML / PNG)
// are in io/nav_grid_files.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/query/map_query.hpp"

namespace slamvdb {

inline constexpr int8_t kUnknownCost = -1;
inline constexpr int8_t kLethalCost = 100;

struct NavGridOptions {
  double robot_height = 1.5;  // metres above the ground that must be free to pass
  // Cost of each query-set class (by index); kUnknownCost leaves its columns unknown.
  std::vector<int8_t> class_cost;
  // Ground whose voxel_confidence is below this is uncertain: its class is kept, its cost is
  // unknown, so that a planner does not drive on a guess (0: off).
  float min_confidence = 0.f;
  // Only the occupied cells whose centre lies in this region count (classify --bbox / --near
  // --grid, GET /api/nav-grid): the grid covers the columns they occupy, and a box's z range also
  // limits the ground and obstacles seen (give one that holds both). Pass the cells of
  // classify_region for the same region. None: the whole map.
  std::optional<QueryRegion> region;
  // Metres per grid cell: 0 for the map's index cell, else a whole multiple k of it (1..64): each
  // grid cell is then the worst of its k x k index cells (lethal if one is; else the highest known
  // cost; unknown only if all are), so that a coarse grid never hides an obstacle.
  double resolution = 0;
};

// The factor k of a grid `resolution` over the map's `cell` (0: 1); throws Error naming both when
// it is not a whole multiple in 1..64.
int nav_grid_factor(double resolution, double cell);

// The default cost of a class name: the paper's terrain classes (smooth 0, rough 30, bumpy 60,
// obstacle 100, active 100: moving things, void unknown); nullopt for other names.
std::optional<int8_t> default_terrain_cost(const std::string& class_name);

// The cost of every class of a query set (by index): `overrides` (CLASS=COST, -1..100) first,
// then default_terrain_cost. Throws Error naming the item or the class: an override that is not
// CLASS=COST or names no class of the set, a class with neither (a planner must not guess).
std::vector<int8_t> nav_class_costs(const std::vector<std::string>& class_names,
                                    const std::vector<std::string>& overrides);

// The path driven, as far as the map knows it: the submap anchors (x, y) in the order they were made.
std::vector<Eigen::Vector2d> submap_path(const SemanticMap& map);

struct NavGrid {
  int width = 0, height = 0;
  double resolution = 0.0;           // metres per cell (the map's index cell)
  Eigen::Vector2d origin{0, 0};      // world x, y of the lower-left corner of cell (0, 0)
  // Row-major from the south (row 0 is the lowest y), as ROS OccupancyGrid.
  std::vector<int8_t> cost;          // 0..100, kUnknownCost
  std::vector<int16_t> ground_class; // query-set class of the ground, -1 unknown
  std::vector<uint8_t> obstacle;     // 1: something within the robot height above the ground
  std::vector<uint8_t> uncertain;    // 1: ground class below min_confidence (cost unknown)
  std::size_t index(int col, int row) const { return static_cast<std::size_t>(row) * width + col; }
  // Cell containing a world point (may be outside the grid).
  Eigen::Vector2i cell_of(double x, double y) const;
};

// `cells`: the map classified (classify_map, or classify_region for options.region), any order.
// Throws Error when class_cost does not have one entry per class used, or the map (the region) has
// no occupied cell (NavGridEmpty).
class NavGridEmpty : public Error {
 public:
  using Error::Error;
};
NavGrid build_nav_grid(const SemanticMap& map, const std::vector<ClassifiedCell>& cells, const NavGridOptions& options);

}  // namespace slamvdb
