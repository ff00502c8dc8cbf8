#pragma once
// GET /api/nav-grid: the navigation grid of a region as `slamvdb classify --bbox ... --grid PREFIX`
// builds and writes it (query/nav_grid.hpp, io/nav_grid_files.hpp: the same functions), answered
// as JSON (costs + the map_server YAML), or as the PGM, the PNG or the YAML alone.
#include <string>

#include "slamvdb/server/map_answers.hpp"

namespace slamvdb {

// The image file the YAML of an answer names (a client saves the PGM under this name beside it).
inline constexpr const char* kNavGridPgmName = "nav-grid.pgm";

struct NavGridAnswer {
  std::string body, content_type;
};

// Refusals (RequestError): no query set (400), a resolution that is not a whole multiple of the map's cell
// (400 naming resolution), a class without a cost (400: the server's --cost), a region holding more than
// `max_cells` semantic cells or spanning more than `max_cells` grid cells (413), a region without
// occupied cells (404 naming the region's field).
NavGridAnswer answer_nav_grid(const AnswerContext& context, const NavGridRequest& request, std::size_t max_cells);

}  // namespace slamvdb
