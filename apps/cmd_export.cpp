// `slamvdb export`: a map file as a coloured PLY point cloud and/or a bird's-eye PNG, semantic voxels
// coloured by a PCA of their embeddings, the others grey by height.
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include "command_registry.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/map_export.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli {
namespace {
namespace fs = std::filesystem;

struct Options {
  std::string map;
  std::string ply;
  std::string png;
  bool ascii = false;
  double resolution = 0.0;
  bool hill_shading = false;
};

// Checked before the (possibly long) load, so a typo costs no time.
void check_output_dir(const std::string& file, const char* option) {
  const fs::path dir = fs::absolute(file).parent_path();
  if (!fs::is_directory(dir)) throw Error(fmt::format("{} {}: directory {} does not exist", option, file, dir.string()));
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

void run(const Options& opt) {
  if (opt.ply.empty() && opt.png.empty()) throw Error("nothing to export: give --ply FILE and/or --png FILE");
  if (!opt.ply.empty()) check_output_dir(opt.ply, "--ply");
  if (!opt.png.empty()) check_output_dir(opt.png, "--png");
  if (opt.resolution < 0) throw Error(fmt::format("--resolution {} must be > 0 (or 0 for automatic)", opt.resolution));

  auto start = std::chrono::steady_clock::now();
  const SemanticMap map = load_map(opt.map);
  const std::vector<ColouredVoxel> voxels = colour_by_pca(map);
  fmt::print("loaded {} ({} occupied, {} semantic voxels) and coloured it in {:.1f} s\n", opt.map, voxels.size(),
             map.num_semantic_voxels(), seconds_since(start));

  if (!opt.ply.empty()) {
    start = std::chrono::steady_clock::now();
    std::optional<ProgressBar> bar;
    write_ply(opt.ply, voxels, opt.ascii ? PlyEncoding::kAscii : PlyEncoding::kBinaryLittleEndian,
              [&](std::size_t done, std::size_t total) {
                if (!bar) bar.emplace("export ply", total);
                bar->update(done);
              });
    if (bar) bar->finish();
    fmt::print("PLY  {}: {} vertices ({}), {:.1f} MB in {:.1f} s\n", opt.ply, voxels.size(),
               opt.ascii ? "ascii" : "binary little endian", static_cast<double>(fs::file_size(opt.ply)) / 1e6,
               seconds_since(start));
  }
  if (!opt.png.empty()) {
    start = std::chrono::steady_clock::now();
    BirdsEyeParams params;
    params.resolution = opt.resolution;
    params.hill_shading = opt.hill_shading;
    const BirdsEyeImage image = render_birds_eye(voxels, map.params().occupancy.voxel_size, params);
    write_png(opt.png, image);
    fmt::print("PNG  {}: {}x{} px at {:.3f} m per pixel in {:.1f} s\n", opt.png, image.rgb.cols, image.rgb.rows,
               image.resolution, seconds_since(start));
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "export",
      "Export a map as a PLY point cloud (occupied voxel centres in the world frame with colour and observation "
      "count) and/or a bird's-eye PNG. Semantic voxels are coloured by the first three principal components of "
      "their embeddings, the others grey by height.");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required();
  cmd->add_option("--ply", opt->ply, "Write the point cloud to this .ply file");
  cmd->add_option("--png", opt->png, "Write the bird's-eye picture to this .png file");
  cmd->add_flag("--ascii", opt->ascii, "Write the PLY as ASCII text instead of binary little endian");
  cmd->add_option("--resolution", opt->resolution,
                  "Bird's-eye metres per pixel (default: the voxel size, coarser if the picture would exceed 2000 px)")
      ->check(finite_range(0, bounds::kMaxResolution));
  cmd->add_flag("--hillshade", opt->hill_shading, "Shade the bird's-eye picture by the terrain's relief");
  cmd->callback([opt] { run(*opt); });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli
