// The navigation grid on a hand-made scene: flat ground, a wall (an obstacle), an overhang above the
// robot's height (not an obstacle), classes and their costs, and the PGM + YAML placing every cell
// back in the world as map_server reads it.
#include "slamvdb/io/nav_grid_files.hpp"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

// Ground z = 0 over [-3, 3]^2, a wall at x = 2 (|y| < 1, 0.3..1.0 m), a plank at 2.2 m over
// x in [-2.5, -1.5]; one scan from (0, 0, 1).
SemanticMap scene() {
  MapParams params;
  params.semantic.dim = 4;
  params.submap_length = 0;
  SemanticMap map(params);
  std::vector<Vec3f> points;  // sensor frame = world - (0, 0, 1)
  for (float x = -3; x <= 3; x += 0.1f)
    for (float y = -3; y <= 3; y += 0.1f) points.emplace_back(x, y, -0.99f);
  for (float y = -1; y <= 1; y += 0.1f)
    for (float z = 0.3f; z <= 1.0f; z += 0.1f) points.emplace_back(2.05f, y, z - 1.0f);
  for (float x = -2.5f; x <= -1.5f; x += 0.1f)
    for (float y = -0.5f; y <= 0.5f; y += 0.1f) points.emplace_back(x, y, 1.2f);
  Pose T = Pose::Identity();
  T.translation() = Vec3d(0, 0, 1);
  map.integrate_scan(0.0, points, T);
  map.finish_active_submap();
  return map;
}

// Every ground cell classified: class 1 ("rough") where y > 0, class 0 ("smooth") elsewhere.
std::vector<ClassifiedCell> classify_ground(const SemanticMap& map) {
  std::vector<ClassifiedCell> cells;
  const double res = map.params().index_cell();
  for (const WorldOccupancyCell& c : map.world_occupancy()) {
    if (c.log_odds < map.params().occupancy.occupied_threshold || c.cell.z() != 0) continue;
    const Vec3d p = center_of_key(c.cell, res);
    cells.push_back({c.cell, p, 1, QueryMatch{p.y() > 0 ? 1 : 0, 0.9f, 0.2f}});
  }
  return cells;
}

int8_t cost_at(const NavGrid& g, double x, double y) {
  const Eigen::Vector2i c = g.cell_of(x, y);
  return g.cost[g.index(c.x(), c.y())];
}

TEST(NavGrid, GroundClassesObstaclesAndOverhangs) {
  const SemanticMap map = scene();
  NavGridOptions options;
  options.robot_height = 1.5;
  options.class_cost = {0, 30};
  const NavGrid grid = build_nav_grid(map, classify_ground(map), options);
  EXPECT_DOUBLE_EQ(grid.resolution, 0.25);
  EXPECT_EQ(cost_at(grid, 1.0, -1.0), 0);     // smooth ground
  EXPECT_EQ(cost_at(grid, 1.0, 1.3), 30);     // rough ground
  EXPECT_EQ(cost_at(grid, 2.1, 0.0), kLethalCost);   // the wall stands on the ground within 1.5 m
  EXPECT_NE(cost_at(grid, -2.0, 0.0), kLethalCost);  // the plank is 2.2 m up: passable
  options.robot_height = 2.5;                       // a taller robot does not fit under it
  EXPECT_EQ(cost_at(build_nav_grid(map, classify_ground(map), options), -2.0, 0.0), kLethalCost);
  options.class_cost = {0};  // no cost for class 1
  EXPECT_THROW(build_nav_grid(map, classify_ground(map), options), Error);
}

TEST(NavGrid, PgmAndYamlPlaceCellsInTheWorld) {
  const SemanticMap map = scene();
  NavGridOptions options;
  options.class_cost = {0, 30};
  const NavGrid grid = build_nav_grid(map, classify_ground(map), options);
  testing::TempDir tmp;
  const NavGridFiles files = write_nav_grid(tmp.path / "nav", grid, {"smooth", "rough"}, {{0, 200, 0}, {200, 150, 0}});
  const YAML::Node yaml = YAML::LoadFile(files.yaml.string());
  EXPECT_EQ(yaml["image"].as<std::string>(), "nav.pgm");
  EXPECT_EQ(yaml["mode"].as<std::string>(), "raw");
  const double res = yaml["resolution"].as<double>(), ox = yaml["origin"][0].as<double>(),
               oy = yaml["origin"][1].as<double>();
  const cv::Mat pgm = cv::imread(files.pgm.string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(pgm.type(), CV_8UC1);
  ASSERT_EQ(pgm.cols, grid.width);
  // map_server: pixel (col, row) covers x = ox + col * res, y = oy + (rows - 1 - row) * res.
  const auto pixel = [&](double x, double y) {
    const int col = static_cast<int>(std::floor((x - ox) / res));
    const int row = pgm.rows - 1 - static_cast<int>(std::floor((y - oy) / res));
    return pgm.at<uint8_t>(row, col);
  };
  EXPECT_EQ(pixel(2.1, 0.0), 100);  // the wall
  EXPECT_EQ(pixel(1.0, 1.3), 30);   // rough
  EXPECT_EQ(pixel(1.0, -1.0), 0);   // smooth
  EXPECT_EQ(pixel(10.0 * res + ox, oy - 100.0 * res + 100.0 * res), pgm.at<uint8_t>(pgm.rows - 1, 10));
  const cv::Mat png = cv::imread(files.png.string());
  EXPECT_EQ(png.cols % grid.width, 0);  // enlarged by a whole factor for its legend
}

TEST(NavGrid, UncertainGroundIsUnknownToThePlannerAndHatched) {
  const SemanticMap map = scene();
  std::vector<ClassifiedCell> cells = classify_ground(map);
  for (ClassifiedCell& c : cells) c.confidence = c.position_world.x() < 0 ? 0.1f : 0.9f;  // west: unsure
  NavGridOptions options;
  options.class_cost = {0, 30};
  const NavGrid sure = build_nav_grid(map, cells, options);  // threshold off: every class counts
  EXPECT_EQ(cost_at(sure, -1.0, -1.0), 0);
  options.min_confidence = 0.5f;
  const NavGrid grid = build_nav_grid(map, cells, options);
  EXPECT_EQ(cost_at(grid, -1.0, -1.0), kUnknownCost);  // smooth, but not sure of it
  EXPECT_EQ(cost_at(grid, -1.0, 1.3), kUnknownCost);
  EXPECT_EQ(cost_at(grid, 1.0, 1.3), 30);              // sure
  EXPECT_EQ(cost_at(grid, 2.1, 0.0), kLethalCost);     // obstacles stay, whatever the class
  const Eigen::Vector2i west = grid.cell_of(-1.0, -1.0);
  EXPECT_EQ(grid.uncertain[grid.index(west.x(), west.y())], 1);
  EXPECT_EQ(grid.ground_class[grid.index(west.x(), west.y())], 0);  // the class is kept
  std::size_t uncertain = 0;
  for (const uint8_t u : grid.uncertain) uncertain += u;
  EXPECT_GT(uncertain, 100u);
  // The picture hatches them: the hatch colour appears only with uncertain ground.
  testing::TempDir tmp;
  const auto hatch_pixels = [&](const NavGrid& g, const char* name) {
    const NavGridFiles files =
        write_nav_grid(tmp.path / name, g, {"smooth", "rough"}, {{0, 200, 0}, {200, 150, 0}}, {}, 0.5f);
    cv::Mat mask;
    const cv::Mat png = cv::imread(files.png.string());
    cv::inRange(png, cv::Scalar(kHatchColour[2], kHatchColour[1], kHatchColour[0]),
                cv::Scalar(kHatchColour[2], kHatchColour[1], kHatchColour[0]), mask);
    return cv::countNonZero(mask);
  };
  EXPECT_GT(hatch_pixels(grid, "uncertain"), 1000);
  EXPECT_LT(hatch_pixels(sure, "sure"), 200);  // at most the text's anti-aliasing
}

}  // namespace
}  // namespace slamvdb
