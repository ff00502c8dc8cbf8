#pragma once
// Files written from a classified map, shared by `classify`, `export` and `demo`.
#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <vector>

#include "slamvdb/core/csv.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/map_export.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/html_viewer.hpp"
#include "slamvdb/io/map_pictures.hpp"
#include "slamvdb/io/nav_grid_files.hpp"
#include "slamvdb/query/nav_grid.hpp"
#include "slamvdb/map/keys.hpp"

#include <absl/container/flat_hash_map.h>
#include "slamvdb/ontology/ontology.hpp"
#include "slamvdb/query/class_summary.hpp"
#include "slamvdb/query/map_query.hpp"

namespace slamvdb::cli {

// One row per semantic voxel of the index (cell centre in the world frame):
// x,y,z,class,score,margin,count,confidence; the class is `uncertain` below min_confidence (score
// and margin stay the best class's). `cells` in the order to write (sort_by_cell for a stable file).
// With `sessions` (the map's), a last column last_session: the name of the newest session that
// observed the voxel (issue 23).
inline void write_classified_csv(const std::filesystem::path& path, const std::vector<ClassifiedCell>& cells,
                                 const QuerySet& queries, float min_confidence = 0.f,
                                 const std::vector<SessionInfo>* sessions = nullptr) {
  CsvWriter csv = sessions ? CsvWriter({"x", "y", "z", "class", "score", "margin", "count", "confidence", "last_session"})
                           : CsvWriter({"x", "y", "z", "class", "score", "margin", "count", "confidence"});
  for (const ClassifiedCell& c : cells) {  // classified_columns(), classified_row()
    const std::vector<std::string> r = classified_row(c, queries, min_confidence);
    if (sessions) csv.row({r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], session_name(*sessions, c.last_session)});
    else csv.row({r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]});
  }
  write_output_file(path, csv.text());
}


// The map's occupied voxels in the world, semantic ones coloured by `colour_of(index into cells)`
// when `cells` has them (any subset, e.g. search results), the others grey by height (dimmed).
template <class Colour>
std::vector<ColouredVoxel> coloured_map(const SemanticMap& map, const std::vector<ClassifiedCell>& cells, Colour&& colour_of) {
  std::vector<ColouredVoxel> voxels = colour_occupied_voxels(map, [](const float*) { return Rgb{0, 0, 0}; });
  absl::flat_hash_map<IndexCellKey, std::size_t> index_of;
  index_of.reserve(cells.size());
  for (std::size_t j = 0; j < cells.size(); ++j) index_of.emplace(cells[j].cell, j);
  const double inv_cell = 1.0 / map.params().index_cell();
  for (ColouredVoxel& v : voxels) {
    const auto it = v.count ? index_of.find(key_of_point<IndexCellKey>(v.position.cast<double>(), inv_cell))
                            : index_of.end();
    if (it != index_of.end()) {
      v.rgb = colour_of(it->second);
    } else {
      // Context without semantics (or not among the cells): dimmed, so that no class colour (the
      // ontology's smooth is a light grey) is mistaken for it.
      if (v.count) v.rgb = {128, 128, 128};
      for (uint8_t& ch : v.rgb) ch = static_cast<uint8_t>(ch / 2);
      v.count = 0;
    }
  }
  return voxels;
}


// The terrain seen from above (the ground voxel of every column, coloured by class) with a legend,
// scale bar, north arrow and the driven path; PNG + map_server YAML. `cells` sorted by cell.
inline BirdsEyeImage write_class_picture(const std::filesystem::path& png, const SemanticMap& map,
                                         const std::vector<ClassifiedCell>& cells, const QuerySet& queries,
                                         const std::vector<Eigen::Vector2d>& path,
                                         const std::string& path_label = "path (submap anchors)",
                                         float min_confidence = 0.f,
                                         const std::optional<QueryRegion>& region = std::nullopt) {
  const std::vector<Rgb> colours = class_colours(queries);
  // With a region (classify --bbox / --near): only the voxels whose centre is in it are drawn.
  const auto in_region = [&](std::vector<ColouredVoxel> voxels) {
    if (region) std::erase_if(voxels, [&](const ColouredVoxel& v) { return !region->contains(v.position.cast<double>()); });
    if (voxels.empty()) throw Error("the region holds no occupied voxels to draw");
    return voxels;
  };
  const auto voxels = in_region(coloured_map(map, cells, [&](std::size_t j) {
    const int k = cells[j].match.class_index;
    return k == kNoClass ? Rgb{255, 255, 255} : colours[static_cast<std::size_t>(k)];
  }));
  BirdsEyeParams params;
  params.layer = BirdsEyeParams::Layer::kGround;
  BirdsEyeImage image = render_birds_eye(voxels, map.params().occupancy.voxel_size, params);
  PictureAnnotations notes;
  notes.title = "terrain classes (ground of each column)";
  for (int k = 0; k < queries.size(); ++k) notes.legend.emplace_back(queries.names[k], colours[k]);
  notes.legend.emplace_back("no semantics (dark grey by height)", Rgb{90, 90, 90});
  if (std::any_of(cells.begin(), cells.end(), [&](const ClassifiedCell& c) { return is_uncertain(c, min_confidence); })) {
    // The same voxels rendered the same way, uncertain ones white: the pixels to hatch.
    const auto marked = in_region(coloured_map(map, cells, [&](std::size_t j) {
      return is_uncertain(cells[j], min_confidence) ? Rgb{255, 255, 255} : Rgb{0, 0, 0};
    }));
    const BirdsEyeImage mask = render_birds_eye(marked, map.params().occupancy.voxel_size, params);
    cv::Mat hatched;
    cv::inRange(mask.rgb, cv::Scalar(255, 255, 255), cv::Scalar(255, 255, 255), hatched);
    notes.hatched = hatched;
    notes.legend.emplace_back(uncertain_legend(min_confidence), kHatchColour);
  }
  if (path.size() >= 2) notes.legend.emplace_back(path_label, Rgb{255, 60, 60});
  notes.trajectory = path;
  annotate(image, notes);
  write_png_with_yaml(png, image);
  return image;
}

// A similarity heat map seen from above: the best score of every column on the viridis ramp with
// a colour bar, other occupied voxels grey; PNG + map_server YAML. `cells` sorted by cell, scores
// in match.score.
inline BirdsEyeImage write_score_picture(const std::filesystem::path& png, const SemanticMap& map,
                                         const std::vector<ClassifiedCell>& cells, const std::string& label,
                                         float lo, float hi, const std::vector<Eigen::Vector2d>& path = {}) {
  auto voxels = coloured_map(map, cells, [&](std::size_t j) {
    return score_colour(hi > lo ? (cells[j].match.score - lo) / (hi - lo) : 1.0f);
  });
  // The best score of a column on top: scored voxels (count kept by coloured_map) are lifted
  // above the rest, ordered by score.
  const double inv_cell = 1.0 / map.params().index_cell();
  absl::flat_hash_map<IndexCellKey, float> score_of;
  for (const ClassifiedCell& c : cells) score_of.emplace(c.cell, c.match.score);
  for (ColouredVoxel& v : voxels)
    if (v.count) v.position.z() = 1e6f + score_of.at(key_of_point<IndexCellKey>(v.position.cast<double>(), inv_cell));
  BirdsEyeImage image = render_birds_eye(voxels, map.params().occupancy.voxel_size);
  PictureAnnotations notes;
  notes.colour_bar = PictureAnnotations::ColourBar{label, lo, hi};
  notes.trajectory = path;
  annotate(image, notes);
  write_png_with_yaml(png, image);
  return image;
}

// classes.png (+ .yaml): the terrain class map; nav.pgm / nav.yaml / nav.png: the navigation grid
// with the terrain costs; map.html: the map in 3D by class. `cells` sorted by cell, `path` the
// driven trajectory (world x, y).
inline void write_class_outputs(const std::filesystem::path& out, const SemanticMap& map,
                                const std::vector<ClassifiedCell>& cells, const QuerySet& queries,
                                const std::vector<Eigen::Vector2d>& path, float min_confidence = 0.f) {
  write_class_picture(out / "classes.png", map, cells, queries, path, "path driven", min_confidence);
  NavGridOptions options;
  for (const std::string& name : queries.names) options.class_cost.push_back(default_terrain_cost(name).value_or(50));
  options.min_confidence = min_confidence;
  const std::vector<Rgb> colours = class_colours(queries);
  write_nav_grid(out / "nav", build_nav_grid(map, cells, options), queries.names, colours, path, min_confidence);
  if (html_viewer_available()) {
    HtmlViewerScene scene;
    scene.title = "slamvdb demo: terrain classes (SIMULATED sequence and features)";
    scene.voxel_size = map.params().occupancy.voxel_size;
    for (const ColouredVoxel& v : coloured_map(map, cells, [&](std::size_t j) {
           const int k = cells[j].match.class_index;
           return k == kNoClass ? Rgb{255, 255, 255} : colours[static_cast<std::size_t>(k)];
         })) {
      scene.positions.push_back(v.position.cast<double>());
      scene.colours.push_back(v.rgb);
    }
    for (int k = 0; k < queries.size(); ++k) scene.legend.push_back({queries.names[k], colours[k]});
    write_html_viewer(out / "map.html", scene);
  }
}

// query_<text>.png: the similarity of every voxel to a text query, seen from above.
inline void write_query_outputs(const std::filesystem::path& out, const SemanticMap& map, const std::string& text,
                                const SimulatedEncoderConfig& sim) {
  SimulatedTextEncoder encoder(sim);
  const std::vector<float> q = encoder.encode(text);
  const auto scored = similarity_search(map, q);
  std::vector<ClassifiedCell> cells;
  float lo = 1, hi = -1;
  for (const ScoredCell& c : scored) {
    cells.push_back({c.cell, c.position_world, c.count, {0, c.score, 0}});
    lo = std::min(lo, c.score), hi = std::max(hi, c.score);
  }
  sort_by_cell(cells);
  write_score_picture(out / fmt::format("query_{}.png", text), map, cells, fmt::format("cosine to '{}'", text), lo, hi);
}

}  // namespace slamvdb::cli
