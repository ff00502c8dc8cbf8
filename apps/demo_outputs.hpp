#pragma once
// Files written from a classified map, shared by `classify`, `export` and `demo`.
#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/map_export.hpp"
#include "slamvdb/ontology/ontology.hpp"
#include "slamvdb/query/map_query.hpp"

namespace slamvdb::cli {

// One row per semantic voxel of the index (cell centre in the world frame):
// x,y,z,class,score,margin,count. `cells` in the order to write (sort_by_cell for a stable file).
inline void write_classified_csv(const std::filesystem::path& path, const std::vector<ClassifiedCell>& cells,
                                 const QuerySet& queries) {
  std::ofstream out(path, std::ios::binary);
  out << "x,y,z,class,score,margin,count\n";
  for (const ClassifiedCell& c : cells) {
    const Vec3d& p = c.position_world;
    const std::string name = c.match.class_index == kNoClass ? "" : queries.names[c.match.class_index];
    out << fmt::format("{:.3f},{:.3f},{:.3f},{},{:.6f},{:.6f},{}\n", p.x(), p.y(), p.z(), name, c.match.score,
                       c.match.margin, c.count);
  }
  if (!out.flush()) throw Error(fmt::format("cannot write {}", path.string()));
}

// The map's occupied voxels in the world, semantic ones coloured by `colour_of(cell index)`, the
// others grey by height (see colour_occupied_voxels).
template <class Colour>
std::vector<ColouredVoxel> coloured_map(const SemanticMap& map, const std::vector<ClassifiedCell>& cells, Colour&& colour_of) {
  std::vector<ColouredVoxel> voxels = colour_occupied_voxels(map, [](const float*) { return Rgb{0, 0, 0}; });
  // colour_occupied_voxels writes cells in key order, as sort_by_cell sorts `cells`: match by position.
  std::size_t j = 0;
  for (ColouredVoxel& v : voxels) {
    if (v.count == 0) continue;
    while (j < cells.size() && (cells[j].position_world.cast<float>() - v.position).squaredNorm() > 1e-6f) ++j;
    if (j < cells.size()) v.rgb = colour_of(j);
  }
  return voxels;
}

// classes.png: the bird's-eye class map (`cells` sorted by cell).
inline void write_class_outputs(const std::filesystem::path& out, const SemanticMap& map,
                                const std::vector<ClassifiedCell>& cells, const QuerySet& queries, const Ontology&) {
  const auto voxels = coloured_map(map, cells, [&](std::size_t j) {
    const int k = cells[j].match.class_index;
    if (k == kNoClass || queries.colours.empty()) return Rgb{255, 255, 255};
    return Rgb{queries.colours[k][0], queries.colours[k][1], queries.colours[k][2]};
  });
  write_png(out / "classes.png", render_birds_eye(voxels, map.params().occupancy.voxel_size));
}

// query_<text>.png: the similarity of every voxel to a text query, seen from above.
inline void write_query_outputs(const std::filesystem::path& out, const SemanticMap& map, const std::string& text,
                                const SimulatedEncoderConfig& sim) {
  SimulatedTextEncoder encoder(sim);
  const std::vector<float> q = encoder.encode(text);
  const auto scored = similarity_search(map, q);
  std::vector<ClassifiedCell> cells;
  for (const ScoredCell& c : scored) cells.push_back({c.cell, c.position_world, c.count, {0, c.score, 0}});
  sort_by_cell(cells);
  const auto voxels = coloured_map(map, cells, [&](std::size_t j) {
    const float t = std::clamp(cells[j].match.score, 0.0f, 1.0f);  // cosine 0..1: blue..yellow
    return Rgb{static_cast<uint8_t>(255 * t), static_cast<uint8_t>(200 * t), static_cast<uint8_t>(255 * (1 - t))};
  });
  write_png(out / fmt::format("query_{}.png", text), render_birds_eye(voxels, map.params().occupancy.voxel_size));
}

}  // namespace slamvdb::cli
