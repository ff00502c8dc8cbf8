// `slamvdb export`: a map for other tools and for people. The format follows the output's
// extension (or --format): PLY and PCD point clouds, a bird's-eye PNG with a map_server YAML, a CSV
// of the semantic voxels, the embeddings as .npy, or a self-contained HTML 3D view. Semantic voxels
// are coloured by class with --queries, else by a PCA of their embeddings; the others grey by
// height. Every output is deterministic (voxels in key order) and written atomically.
#include <fmt/format.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>

#include "colour_basis_option.hpp"
#include "command_registry.hpp"
#include "demo_outputs.hpp"
#include "feature_options.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "progress.hpp"
#include "session_option.hpp"
#include "slamvdb/core/csv.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/html_viewer.hpp"
#include "slamvdb/io/map_export.hpp"
#include "slamvdb/io/map_pictures.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_export {
namespace {
namespace fs = std::filesystem;

const std::vector<std::string> kFormats = {"ply", "pcd", "png", "csv", "npy", "html"};

struct Options {
  std::string map, queries, format;
  std::vector<std::string> outputs;  // -o (repeatable), --ply and --png
  std::string ply, png;
  bool ascii = false, hill_shading = false, no_void_rule = false, ignore_model_id = false;
  double resolution = 0.0;
  std::string layer = "auto";
  ColourBasisChoice colour_basis;
  std::vector<std::string> sessions;  // empty: every session
  std::vector<std::string> last_sessions;  // empty: every voxel; else those last observed by these
};

// The format of an output: --format for a single output, else its extension.
std::string format_of(const std::string& output, const std::string& forced) {
  if (!forced.empty()) return forced;
  std::string ext = fs::path(output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (!ext.empty()) ext.erase(0, 1);
  if (std::find(kFormats.begin(), kFormats.end(), ext) == kFormats.end())
    usage_error(fmt::format("-o {}: cannot tell the format from '{}'; use .ply, .pcd, .png, .csv, .npy or .html "
                            "(or --format)",
                            output, fs::path(output).extension().string()));
  return ext;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

void run(Options opt) {
  const auto start = std::chrono::steady_clock::now();
  if (!opt.colour_basis.file.empty()) {  // checked against the map's summary before loading it
    const MapFileSummary summary = read_map_summary(opt.map);
    check_colour_basis_option(opt.colour_basis, summary.params.semantic.dim);
    if (opt.colour_basis.model_id != summary.info.model_id && !opt.ignore_model_id)
      throw Error(fmt::format("--colour-basis {} is in embedding space '{}' but {} is in '{}' (--ignore-model-id if "
                              "they are the same space)",
                              opt.colour_basis.file, escape_control(opt.colour_basis.model_id), opt.map,
                              escape_control(summary.info.model_id)));
  }
  if (!opt.last_sessions.empty()) {  // names checked before any voxel is read
    try {
      sessions::session_ids_named(read_map_summary(opt.map).info, opt.last_sessions);
    } catch (const Error& e) {
      throw Error(fmt::format("--last-session: {}: {}", opt.map, e.what()));
    }
  }
  SemanticMap map = load_map_of_sessions(opt.map, opt.sessions);
  if (!opt.last_sessions.empty()) {
    const sessions::LastObservedSelection kept = sessions::keep_last_observed(map, opt.last_sessions);
    fmt::print(stderr, "--last-session {}: {} of {} semantic voxels were last observed by it\n",
               fmt::join(opt.last_sessions, ","), kept.semantic_voxels_kept,
               kept.semantic_voxels_kept + kept.semantic_voxels_removed);
  }
  std::optional<QuerySet> queries;
  std::vector<ClassifiedCell> cells;
  if (!opt.queries.empty()) {
    queries = load_query_set(opt.queries);
    ClassifyOptions options;
    options.void_to_second_best = !opt.no_void_rule;
    cells = classify_map(map, *queries, options, opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch);
    sort_by_cell(cells);
  }
  std::vector<Rgb> colours;
  if (queries) colours = class_colours(*queries);
  const std::vector<ColouredVoxel> voxels =
      queries ? coloured_map(map, cells, [&](std::size_t j) {
        const int k = cells[j].match.class_index;
        return k == kNoClass ? Rgb{255, 255, 255} : colours[static_cast<std::size_t>(k)];
      })
              : colour_by_pca(map, opt.colour_basis.basis ? &*opt.colour_basis.basis : nullptr);
  fmt::print("loaded {} ({} occupied voxels, {} semantic cells{}) in {:.1f} s\n", opt.map, voxels.size(),
             map.num_index_cells(), queries ? fmt::format(", classified with {}", opt.queries) : "",
             seconds_since(start));
  std::vector<Eigen::Vector2d> path;
  for (const SubmapInfo& s : map.submaps()) path.push_back(s.T_world_submap.translation().head<2>());

  for (const std::string& output : opt.outputs) {
    const std::string format = format_of(output, opt.outputs.size() == 1 ? opt.format : "");
    const auto t = std::chrono::steady_clock::now();
    if (format == "ply") {
      std::optional<ProgressBar> bar;
      const std::uint64_t bytes = write_ply(output, voxels, opt.ascii ? PlyEncoding::kAscii : PlyEncoding::kBinaryLittleEndian,
                [&](std::size_t done, std::size_t total) {
                  if (!bar) bar.emplace("export ply", total, "voxels");
                  bar->update(done);
                });
      if (bar) bar->finish();
      fmt::print("PLY  {}: {} vertices (x y z float, red green blue uchar, count int), {:.1f} MB", output,
                 voxels.size(), static_cast<double>(bytes) / 1e6);
    } else if (format == "pcd") {
      write_pcd_voxels(output, voxels);
      fmt::print("PCD  {}: {} points (x y z rgb count, binary)", output, voxels.size());
    } else if (format == "png") {
      BirdsEyeParams params;
      params.resolution = opt.resolution;
      params.hill_shading = opt.hill_shading;
      const bool ground = opt.layer == "ground" || (opt.layer == "auto" && queries);
      params.layer = ground ? BirdsEyeParams::Layer::kGround : BirdsEyeParams::Layer::kTop;
      BirdsEyeImage image = render_birds_eye(voxels, map.params().occupancy.voxel_size, params);
      PictureAnnotations notes;
      notes.title = queries ? (ground ? "terrain classes (ground of each column)" : "classes (top of each column)")
                            : (ground ? "PCA of the embeddings (ground of each column)" : "PCA of the embeddings");
      if (queries)
        for (int k = 0; k < queries->size(); ++k) notes.legend.emplace_back(queries->names[k], colours[k]);
      notes.legend.emplace_back("no semantics (grey by height)", Rgb{90, 90, 90});
      if (path.size() >= 2) notes.legend.emplace_back("path (submap anchors)", Rgb{255, 60, 60});
      notes.trajectory = path;
      annotate(image, notes);
      write_png_with_yaml(output, image);
      fmt::print("PNG  {} (+ .yaml): {}x{} px at {:.3f} m per pixel", output, image.rgb.cols, image.rgb.rows,
                 image.resolution);
    } else if (format == "csv") {
      if (queries) {
        write_classified_csv(output, cells, *queries);
        fmt::print("CSV  {}: {} rows x,y,z,class,score,margin,count", output, cells.size());
      } else {
        CsvWriter csv({"x", "y", "z", "count"});
        for (const ColouredVoxel& v : colour_occupied_voxels(map, [](const float*) { return Rgb{}; }))
          if (v.count)
            csv.row({fmt::format("{:.3f}", v.position.x()), fmt::format("{:.3f}", v.position.y()),
                     fmt::format("{:.3f}", v.position.z()), fmt::format("{}", v.count)});
        write_output_file(output, csv.text());
        fmt::print("CSV  {}: {} rows x,y,z,count (give --queries for class,score,margin)", output, csv.rows());
      }
    } else if (format == "npy") {
      const std::size_t n = write_embeddings_npy(output, map);
      fs::path base = output;
      base.replace_extension();
      fmt::print("NPY  {} ({} x {} float32 embeddings) + {}.positions.npy + {}.counts.npy", output, n,
                 map.params().semantic.dim, base.string(), base.string());
    } else {  // html
      HtmlViewerScene scene;
      scene.title = fmt::format("slamvdb map {}", fs::path(opt.map).filename().string());
      scene.voxel_size = map.params().occupancy.voxel_size;
      for (const ColouredVoxel& v : voxels) scene.positions.push_back(v.position.cast<double>()), scene.colours.push_back(v.rgb);
      if (queries)
        for (int k = 0; k < queries->size(); ++k) scene.legend.push_back({queries->names[k], colours[k]});
      write_html_viewer(output, scene);
      fmt::print("HTML {}: {} voxels in a 3D view, open it in a browser", output, voxels.size());
    }
    fmt::print(" ({:.1f} s)\n", seconds_since(t));
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "export",
      "Export a map for other tools and people; the format follows each output's extension: .ply / .pcd (occupied "
      "voxel centres, world frame, colour, observation count), .png (bird's-eye picture with legend, scale and a "
      "map_server .yaml), .csv (one row per semantic voxel), .npy (embeddings, positions, counts), .html (3D view). "
      "Semantic voxels are coloured by class with --queries, else by a PCA of their embeddings; the others grey by "
      "height.");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required();
  cmd->add_option("-o,--output", opt->outputs, "Output file(s): .ply .pcd .png .csv .npy .html (repeatable)");
  cmd->add_option("--format", opt->format, "The format of a single -o whose extension says otherwise")
      ->check(CLI::IsMember(kFormats));
  cmd->add_option("--ply", opt->ply, "Same as -o FILE.ply (kept for old scripts)");
  cmd->add_option("--png", opt->png, "Same as -o FILE.png (kept for old scripts)");
  cmd->add_option("--queries", opt->queries, "Query set: colour and label voxels by class (CSV: class,score,margin)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--ascii", opt->ascii, "Write the PLY as ASCII text instead of binary little endian");
  cmd->add_option("--resolution", opt->resolution,
                  "Bird's-eye metres per pixel (default: the voxel size, coarser if the picture would exceed 2000 px)")
      ->check(finite_range(0, bounds::kMaxResolution));
  cmd->add_option("--layer", opt->layer,
                  "Bird's-eye: 'top' (highest voxel of a column), 'ground' (lowest: the terrain under tree crowns) "
                  "or 'auto' (ground with --queries, else top)")
      ->check(CLI::IsMember({"auto", "top", "ground"}))
      ->capture_default_str();
  cmd->add_flag("--hillshade", opt->hill_shading, "Shade the bird's-eye picture by the terrain's relief");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "With --queries: let void classes win");
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "With --queries or --colour-basis: accept another model id (same dim)");
  add_colour_basis_option(cmd, opt->colour_basis);
  add_session_option(cmd, opt->sessions, "Only these sessions' submaps (as `info` lists them; repeatable)");
  cmd->add_option("--last-session", opt->last_sessions,
                  "What changed between drives: only the semantic voxels whose newest observation is from these "
                  "sessions (the others stay as grey context)")
      ->delimiter(',')
      ->type_name("NAME[,NAME]");
  add_option_checks(cmd, [opt] {
    if (!opt->colour_basis.file.empty() && !opt->queries.empty())
      usage_error("--colour-basis colours by PCA; with --queries the colours are the classes'");
    if (!opt->ply.empty()) opt->outputs.push_back(opt->ply);
    if (!opt->png.empty()) opt->outputs.push_back(opt->png);
    if (opt->outputs.empty()) usage_error("nothing to export: give -o FILE (.ply .pcd .png .csv .npy .html)");
    if (!opt->format.empty() && opt->outputs.size() > 1) usage_error("--format applies to a single -o");
    if (!opt->ply.empty() && format_of(opt->ply, "") != "ply") usage_error(fmt::format("--ply {}: not a .ply name", opt->ply));
    if (!opt->png.empty() && format_of(opt->png, "") != "png") usage_error(fmt::format("--png {}: not a .png name", opt->png));
    for (const std::string& output : opt->outputs) {
      const std::string format = format_of(output, opt->outputs.size() == 1 ? opt->format : "");
      if (format == "html" && !html_viewer_available())
        usage_error("-o " + output + ": this slamvdb was built without the HTML viewer (npm ci --prefix viewer)");
    }
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("map", opt->map);
  io->input("--queries", opt->queries);
  io->input("--colour-basis", opt->colour_basis.file);
  // -o, with --ply and --png added to it once parsed; a PNG has its .yaml, an NPY three files.
  io->output("-o", opt->outputs, [opt](const std::string& output) -> std::vector<fs::path> {
    const std::string format = format_of(output, opt->outputs.size() == 1 ? opt->format : "");
    if (format == "png") return png_with_yaml(output);
    if (format == "npy") return embeddings_npy_files(output);
    return {output};
  });
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_export
