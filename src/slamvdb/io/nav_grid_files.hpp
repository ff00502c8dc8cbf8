#pragma once
// A navigation grid on disk: PREFIX.pgm + PREFIX.yaml in the ROS map_server / Nav2 "raw" mode
// (each pixel is the cost, 0 free .. 100 lethal, 255 unknown), and PREFIX.png, the same grid in
// the terrain classes' colours (obstacles black, unknown grey) with a legend, scale and north.
#include <filesystem>
#include <string>
#include <vector>

#include "slamvdb/io/map_pictures.hpp"
#include "slamvdb/query/nav_grid.hpp"
#include "slamvdb/query/query_set.hpp"

namespace slamvdb {

struct NavGridFiles {
  std::filesystem::path pgm, yaml, png;
};

// The files of a grid written with `prefix` (PREFIX.pgm, .yaml, .png).
NavGridFiles nav_grid_files(const std::filesystem::path& prefix);

// The colour of each class of a query set in pictures: its own colours, else spread over the
// score ramp.
std::vector<Rgb> class_colours(const QuerySet& queries);

// A grid's files as bytes (what write_nav_grid writes; GET /api/nav-grid answers them): the PGM,
// the annotated PNG, and the map_server YAML naming `pgm_name` as its image.
struct NavGridBytes {
  std::string pgm, png, yaml;
};
NavGridBytes encode_nav_grid(const NavGrid& grid, const std::string& pgm_name,
                             const std::vector<std::string>& class_names, const std::vector<Rgb>& class_colours,
                             const std::vector<Eigen::Vector2d>& trajectory = {}, float min_confidence = 0.f);

// class_names / class_colours: of the query set the grid was classified with. Uncertain ground
// (grid.uncertain) is drawn in its class's colour, hatched, with a legend line naming
// min_confidence (the grid's NavGridOptions::min_confidence).
NavGridFiles write_nav_grid(const std::filesystem::path& prefix, const NavGrid& grid,
                            const std::vector<std::string>& class_names, const std::vector<Rgb>& class_colours,
                            const std::vector<Eigen::Vector2d>& trajectory = {}, float min_confidence = 0.f);

// The PGM's pixel for a cost (raw mode).
inline uint8_t nav_pgm_value(int8_t cost) { return cost < 0 ? 255 : static_cast<uint8_t>(cost); }

}  // namespace slamvdb
