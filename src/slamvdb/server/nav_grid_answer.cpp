#include "slamvdb/server/nav_grid_answer.hpp"

#include <fmt/format.h>

#include <cmath>

#include "slamvdb/io/nav_grid_files.hpp"
#include "slamvdb/query/class_summary.hpp"

namespace slamvdb {

namespace nav_grid_answer_detail {

// The field a region refusal names: its box when it has one, else its centre.
std::string region_field(const QueryRegion& region) { return region.box ? "bbox" : "near"; }

// Grid cells the region can span in x and y at `resolution` (its bounds; a ball's or cylinder's
// square), checked before anything is built.
double region_grid_cells(const QueryRegion& region, double resolution) {
  const Eigen::AlignedBox3d b = region.bounds();
  return (std::floor((b.max().x() - b.min().x()) / resolution) + 2) *
         (std::floor((b.max().y() - b.min().y()) / resolution) + 2);
}

}  // namespace nav_grid_answer_detail

NavGridAnswer answer_nav_grid(const AnswerContext& context, const NavGridRequest& request, std::size_t max_cells) {
  using namespace nav_grid_answer_detail;
  if (!context.queries)
    throw RequestError(400, "", "GET /api/nav-grid needs a query set: this server was started without --queries");
  const QuerySet& queries = *context.queries;
  const double resolution = context.map->grid_resolution();
  if (request.resolution) {
    try {
      nav_grid_factor(*request.resolution, resolution);
    } catch (const Error& e) {
      throw RequestError(400, "resolution", e.what());
    }
  }
  // Refused before building: a grid costs what its region holds and spans.
  if (const std::size_t n = context.map->region_cells(request.region); n > max_cells)
    throw RequestError(413, region_field(request.region),
                       fmt::format("the region holds {}{} semantic cells; GET /api/nav-grid answers at most {} (the "
                                   "server's --max-cells): split the region into smaller boxes",
                                   context.map->source_kind() == "fleet" ? "up to " : "", n, max_cells));
  if (const double span = region_grid_cells(request.region, resolution); span > static_cast<double>(max_cells))
    throw RequestError(413, region_field(request.region),
                       fmt::format("the region spans up to {:.0f} grid cells of {} m; GET /api/nav-grid answers at "
                                   "most {} (the server's --max-cells): split the region into smaller boxes",
                                   span, resolution, max_cells));
  NavGridOptions options;
  options.robot_height = request.robot_height;
  options.min_confidence = request.min_confidence;
  options.region = request.region;
  options.resolution = request.resolution.value_or(0.0);
  try {
    options.class_cost = nav_class_costs(queries.names, context.nav_costs);
  } catch (const Error& e) {
    throw RequestError(400, "", fmt::format("GET /api/nav-grid: {} (an option of `slamvdb serve`)", e.what()));
  }
  MapService::RegionGrid built;
  try {
    built = context.map->nav_grid(queries, options, context.classify, context.model_check);
  } catch (const NavGridEmpty& e) {
    throw RequestError(404, region_field(request.region), e.what());
  } catch (const RequestError&) {
    throw;
  } catch (const DeadlineExceeded&) {
    throw;  // the time budget: 503 (http_server.cpp), not the 400 below
  } catch (const Error& e) {
    throw RequestError(400, "", e.what());  // the query set does not fit the map (its checks' message)
  }
  const NavGrid& grid = built.grid;
  const NavGridBytes bytes = encode_nav_grid(grid, kNavGridPgmName, queries.names, class_colours(queries), built.path,
                                             request.min_confidence);
  switch (request.format) {
    case NavGridRequest::Format::kPgm: return {bytes.pgm, "image/x-portable-graymap"};
    case NavGridRequest::Format::kPng: return {bytes.png, "image/png"};
    case NavGridRequest::Format::kYaml: return {bytes.yaml, "application/yaml"};
    case NavGridRequest::Format::kJson: break;
  }
  std::size_t lethal = 0, unknown = 0, uncertain = 0;
  for (const int8_t c : grid.cost) lethal += c == kLethalCost, unknown += c == kUnknownCost;
  for (const uint8_t u : grid.uncertain) uncertain += u;
  nlohmann::json costs = nlohmann::json::object();
  for (std::size_t k = 0; k < queries.names.size(); ++k) costs[queries.names[k]] = options.class_cost[k];
  const nlohmann::json body = {
      {"encoder", encoder_json(context)},
      {"queries", context.queries_name},
      {"region", region_json(request.region)},
      {"resolution", grid.resolution},
      {"width", grid.width},
      {"height", grid.height},
      {"origin", {grid.origin.x(), grid.origin.y()}},
      {"robot_height", request.robot_height},
      {"min_confidence", request.min_confidence},
      {"class_costs", std::move(costs)},
      {"lethal", lethal},
      {"unknown", unknown},
      {"uncertain", uncertain},
      {"cost", grid.cost},
      {"image", kNavGridPgmName},
      {"yaml", bytes.yaml}};
  return {body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), "application/json"};
}

}  // namespace slamvdb
