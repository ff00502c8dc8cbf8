#pragma once
// --bbox, --near and --radius of `query` and `classify`: the library's region
// (query/query_region.hpp, the same one /api/query's "region" and /api/classes?bbox= make).
#include <CLI/CLI.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "option_checks.hpp"
#include "slamvdb/core/point_text.hpp"
#include "slamvdb/query/query_region.hpp"

namespace slamvdb::cli {

struct RegionOptions {
  std::string bbox, near;
  double radius = 0;  // 0: not given (the option refuses 0)

  // `what`: what the region limits, for the help ("voxels", "voxels classified").
  void add_to(CLI::App* cmd, const std::string& what) {
    cmd->add_option("--bbox", bbox,
                    "Only " + what +
                        " whose centre is in this world box: xmin,ymin,zmin,xmax,ymax,zmax (submaps outside it are "
                        "not read; with --near, the voxel must be in both)");
    cmd->add_option("--near", near,
                    "Only " + what +
                        " within --radius of this world point: x,y,z (a ball) or x,y (a vertical cylinder: distance "
                        "in x and y, any height)");
    cmd->add_option("--radius", radius, "Radius of --near in metres")->check(finite_range(0.0, 1e7, true));
  }
  bool given() const { return !bbox.empty() || !near.empty() || radius > 0; }
  // The region; none of the options: none. A bad one is a usage error naming it.
  std::optional<QueryRegion> region() const {
    if (!given()) return std::nullopt;
    try {
      std::optional<std::vector<double>> box, centre;
      if (!bbox.empty()) box = parse_numbers(bbox, "--bbox", 6, 6, "xmin,ymin,zmin,xmax,ymax,zmax");
      if (!near.empty()) centre = parse_numbers(near, "--near", 2, 3, "x,y or x,y,z");
      return make_region(box ? std::optional<std::span<const double>>(*box) : std::nullopt,
                         centre ? std::optional<std::span<const double>>(*centre) : std::nullopt,
                         radius > 0 ? std::optional<double>(radius) : std::nullopt, {"--bbox", "--near", "--radius"});
    } catch (const Error& e) {
      usage_error(e.what());
    }
  }
};

}  // namespace slamvdb::cli
