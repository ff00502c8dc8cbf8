#pragma once
// `slamvdb export --html`: one self-contained HTML page with an interactive 3D view of coloured
// points (three.js, bundled at build time: viewer/), so a map can be orbited in any browser with
// no network and no install.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

struct HtmlViewerScene {
  std::string title;
  double voxel_size = 0.25;       // m: the drawn point size
  std::vector<Vec3d> positions;   // world frame (m)
  std::vector<Rgb8> colours;      // one per position
  struct LegendEntry {
    std::string name;
    Rgb8 colour;
  };
  std::vector<LegendEntry> legend;  // class colours, when points are coloured by class
  struct ColourBar {
    std::string label;        // e.g. "cosine similarity to 'grass'"
    double min = 0, max = 1;
    std::vector<Rgb8> stops;  // evenly spaced from min to max
  };
  std::optional<ColourBar> colour_bar;  // when points are coloured by a score
};

// Whether this build has the viewer script (needs the npm packages at build time).
bool html_viewer_available();

// Writes the page atomically. Throws Error when the viewer is not built in, when the scene's sizes
// disagree or a position is not finite, and when the file cannot be written.
void write_html_viewer(const std::filesystem::path& path, const HtmlViewerScene& scene);

}  // namespace slamvdb
