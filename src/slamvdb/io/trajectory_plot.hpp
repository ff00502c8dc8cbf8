#pragma once
// A PNG of trajectories seen from above (x right, y up), with a legend, a scale bar and loop edges.
#include <array>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

struct PlotLine {
  std::string label;
  std::vector<Vec3d> positions;
  std::array<unsigned char, 3> rgb{0, 0, 0};
};

// `edges`: pairs of positions joined by a thin line (loop closures). Throws Error on a write failure.
void write_trajectory_plot(const std::filesystem::path& png, const std::vector<PlotLine>& lines,
                           const std::vector<std::pair<Vec3d, Vec3d>>& edges, int size_px = 1000);

}  // namespace slamvdb
