// `slamvdb query`: ask a map questions through its global index (paper section 6.2.5):
// similarity with a text, a class of a query set, an image or a raw vector, composed of positive and
// negative terms (Figure 6.2), or what the map holds at given world points.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "command_registry.hpp"
#include "feature_options.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "map_source_options.hpp"
#include "region_options.hpp"
#include "image_encoder_option.hpp"
#include "text_encoder_option.hpp"
#include "slamvdb/core/csv.hpp"
#include "slamvdb/core/point_text.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "demo_outputs.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/html_viewer.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/io/map_pictures.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/query/query_region.hpp"
#include "slamvdb/query/query_terms.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_query {
namespace {

struct Options {
  std::string queries, output, at_csv, text_model, image_model, ply, png;
  RegionOptions region;
  MapSourceOptions source;
  std::vector<std::string> text, not_text, classes, not_classes, images, at, vectors, not_vectors;
  std::size_t top_k = 100;
  float threshold = -std::numeric_limits<float>::infinity();
  uint64_t sim_seed = 1;
  float sim_text_gap = 0.f;
  bool ignore_model_id = false, no_void_rule = false;
};

// --at and --at-csv, read before the map (core/point_text.hpp: one strict parser for every way a
// point comes in). A bad --at is a usage error; a bad line of the file a runtime error naming it.
std::vector<Vec3d> read_points(const Options& opt) {
  std::vector<Vec3d> points;
  for (const auto& p : opt.at) {
    try {
      points.push_back(parse_point(p, "--at"));
    } catch (const Error& e) {
      usage_error(e.what());
    }
  }
  if (!opt.at_csv.empty()) {
    const PointsText file = read_points_file(opt.at_csv);
    if (file.points.empty())
      throw Error(fmt::format("points file {} holds no point{}", opt.at_csv, file.header ? " (only a header)" : ""));
    points.insert(points.end(), file.points.begin(), file.points.end());
  }
  return points;
}

// The embedding space must be the map's: an encoder of another space answers nothing meaningful.
void check_space(const std::string& what, const std::string& model_id, const SemanticMap& map, bool ignore) {
  if (ignore || model_id == map.info().model_id) return;
  throw Error(fmt::format("{} embeds into '{}' but the map is in '{}' (use the encoder the map was built with, or "
                          "--ignore-model-id if they are the same space)",
                          what, model_id, map.info().model_id));
}

Eigen::VectorXf to_vector(const std::vector<float>& v) { return Eigen::Map<const Eigen::VectorXf>(v.data(), v.size()); }

// The question's terms as the library takes them (query/query_terms.hpp, shared with `slamvdb serve`):
// .npy vectors and images are embedded here, texts and classes by build_query_vector.
Eigen::VectorXf build_query(const Options& opt, const SemanticMap& map) {
  QueryTerms terms;
  terms.text = opt.text;
  terms.not_text = opt.not_text;
  terms.classes = opt.classes;
  terms.not_classes = opt.not_classes;
  std::unique_ptr<TextEncoder> encoder;
  TextEmbedder embed_text;
  if (terms.uses_text()) {
    encoder = open_text_encoder(opt.text_model, map.params().semantic.dim, opt.sim_seed, opt.sim_text_gap);
    check_space("the text encoder", encoder->model_id(), map, opt.ignore_model_id);
    embed_text = [&encoder](std::string_view text) -> Eigen::VectorXf { return to_vector(encoder->encode(text)); };
  }
  std::optional<QuerySet> queries;
  if (terms.uses_classes()) queries = load_query_set(opt.queries);
  const auto read_vectors = [&](const std::vector<std::string>& files, std::vector<Eigen::VectorXf>& into) {
    for (const auto& file : files)
      for (const std::vector<float>& v : read_npy_vectors(file)) {
        if (static_cast<int>(v.size()) != map.params().semantic.dim)
          throw Error(fmt::format("{}: a {}-d vector, but the map's embeddings are {}-d", file, v.size(),
                                  map.params().semantic.dim));
        if (!std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); }))
          throw Error(fmt::format("{}: the vector holds a non-finite value", file));
        into.push_back(to_vector(v));
      }
  };
  read_vectors(opt.vectors, terms.vectors);
  read_vectors(opt.not_vectors, terms.not_vectors);
  if (!opt.images.empty()) {
    const auto image_encoder = open_image_encoder(opt.image_model, map.params().semantic.dim, opt.sim_seed);
    check_space("the image encoder", image_encoder->model_id(), map, opt.ignore_model_id);
    for (const auto& file : opt.images) terms.vectors.push_back(to_vector(image_encoder->embed_file(file)));
  }
  QueryTermSources sources;
  sources.embed_text = encoder ? &embed_text : nullptr;
  sources.queries = queries ? &*queries : nullptr;
  sources.queries_name = opt.queries;
  sources.model_check = opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch;
  return build_query_vector({map.params().semantic.dim, map.info().model_id}, terms, sources);
}

// The output's format from its extension: .csv, .ply, .png (+ .yaml) or .html; "" without output.
std::string output_format(const std::string& output) {
  if (output.empty()) return "";
  std::string ext = std::filesystem::path(output).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext != ".csv" && ext != ".ply" && ext != ".png" && ext != ".html")
    throw CLI::ValidationError("--output", fmt::format("'{}': write .csv, .ply, .png or .html", output));
  return ext;
}

// A cell's weight and spread S/W as the CSVs write them (spread empty when not known: maps before
// format 3).
std::string weight_text(VoxelStatistics s) { return fmt::format("{:.3f}", s.weight); }
std::string spread_text(VoxelStatistics s) {
  return s.known() && s.weight > 0 ? fmt::format("{:.6f}", s.spread / s.weight) : "";
}

// A result's class name ("" without one).
std::string class_text(const QuerySet& queries, const ScoredCell& r) {
  return r.match && r.match->class_index != kNoClass ? queries.names[static_cast<std::size_t>(r.match->class_index)] : "";
}

void run_points(const Options& opt, const SemanticMap& map, const std::vector<Vec3d>& points) {
  std::optional<QuerySet> queries;
  if (!opt.queries.empty()) queries = load_query_set(opt.queries);
  ClassifyOptions options;
  options.void_to_second_best = !opt.no_void_rule;
  const auto answers = query_points(map, points, queries ? &*queries : nullptr, options,
                                    opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch,
                                    /*with_embeddings=*/false);
  // weight / spread: the cell's observation statistics (spread S/W, empty for a map file before format
  // 3); confidence: voxel_confidence of the class (with a query set); last_session: the name of the
  // newest session that observed the cell (issue 23).
  CsvWriter csv({"x", "y", "z", "found", "cell_x", "cell_y", "cell_z", "count", "class", "score", "margin", "weight",
                 "spread", "confidence", "last_session"});
  for (const PointQuery& a : answers) {
    const std::string cls = a.match && a.match->class_index != kNoClass ? queries->names[a.match->class_index] : "";
    csv.row({fmt::format("{}", a.point_world.x()), fmt::format("{}", a.point_world.y()),
             fmt::format("{}", a.point_world.z()), a.found ? "1" : "0", fmt::format("{:.3f}", a.cell_centre.x()),
             fmt::format("{:.3f}", a.cell_centre.y()), fmt::format("{:.3f}", a.cell_centre.z()),
             fmt::format("{}", a.count), cls, a.match ? fmt::format("{:.6f}", a.match->score) : "",
             a.match ? fmt::format("{:.6f}", a.match->margin) : "",
             a.found ? weight_text(a.stats) : "", a.found ? spread_text(a.stats) : "",
             a.match ? fmt::format("{:.4f}", a.confidence) : "",
             a.last_session_name});
  }
  if (opt.output.empty()) {
    // CSV on a terminal: class names are bounded when the query set is loaded (no control
    // characters), so the data are printed as they would be written.
    fmt::print("{}", csv.text());
  } else {
    write_output_file(opt.output, csv.text());
    fmt::print("{} points, {} in a semantic voxel: {}\n", answers.size(),
               std::count_if(answers.begin(), answers.end(), [](const PointQuery& a) { return a.found; }), opt.output);
  }
}

void write_results(const std::string& format, const std::string& output, const Options& opt, const SemanticMap& map,
                   const std::vector<ScoredCell>& results, const QuerySet* queries, float lo, float hi);

void run(const Options& opt) {
  const bool spatial = !opt.at.empty() || !opt.at_csv.empty();
  const bool similarity = !opt.text.empty() || !opt.classes.empty() || !opt.images.empty() || !opt.vectors.empty();
  if (spatial == similarity)
    throw CLI::ValidationError("query",
                               "give either a query (--text, --class, --image, --vector) or points (--at, --at-csv)");
  const std::string format = output_format(opt.output);
  if (spatial && ((!format.empty() && format != ".csv") || !opt.ply.empty() || !opt.png.empty()))
    throw CLI::ValidationError("--output", "point look-ups are written as .csv");
  if ((!opt.classes.empty() || !opt.not_classes.empty()) && opt.queries.empty())
    throw CLI::ValidationError("--class", "needs --queries QUERIES.json");
  const std::optional<QueryRegion> region = opt.region.region();
  if (spatial && region) throw CLI::ValidationError("--bbox", "--bbox and --near limit a similarity query, not --at points");
  const std::vector<Vec3d> points = spatial ? read_points(opt) : std::vector<Vec3d>{};
  SearchOptions search;
  search.top_k = opt.top_k;
  search.threshold = opt.threshold;
  search.region = region;
  // A fleet map is asked for the submaps that can hold the answer only (their summaries bound
  // their best score); not for a PNG, which draws every occupied voxel of the region.
  const bool picture = format == ".png" || !opt.png.empty();
  Eigen::VectorXf q;
  const SemanticMap map =
      !spatial && !opt.source.db.empty() && !picture
          ? opt.source.read_for_search(region, [&](const SemanticMap& shell) { return build_query(opt, shell); }, search, &q)
          : opt.source.read(region);
  if (spatial) return run_points(opt, map, points);

  if (q.size() == 0) q = build_query(opt, map);
  auto results = similarity_search(map, std::span<const float>(q.data(), static_cast<std::size_t>(q.size())), search);
  // With a query set, each result also gets its class and confidence (as query --at gives them).
  std::optional<QuerySet> queries;
  if (!opt.queries.empty()) {
    queries = load_query_set(opt.queries);
    ClassifyOptions options;
    options.void_to_second_best = !opt.no_void_rule;
    classify_results(map, *queries, results, options,
                     opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch);
  }
  fmt::print("{} of {} semantic voxels{}{}:\n", results.size(), map.num_index_cells(),
             opt.top_k ? fmt::format(" (top {})", opt.top_k) : std::string(),
             region ? " in the region (--bbox / --near)" : "");
  fmt::print("| rank | x | y | z | cosine | observations |{}\n|---:|---:|---:|---:|---:|---:|{}\n",
             queries ? " class | confidence |" : "", queries ? "---|---:|" : "");
  for (std::size_t i = 0; i < results.size() && i < 10; ++i) {
    const ScoredCell& r = results[i];
    fmt::print("| {} | {:.2f} | {:.2f} | {:.2f} | {:.4f} | {} |", i + 1, r.position_world.x(), r.position_world.y(),
               r.position_world.z(), r.score, r.count);
    if (queries) fmt::print(" {} | {:.4f} |", class_text(*queries, r), r.confidence);
    fmt::print("\n");
  }
  float lo = 1, hi = -1;
  for (const ScoredCell& r : results) lo = std::min(lo, r.score), hi = std::max(hi, r.score);
  std::vector<std::string> outputs;
  for (const std::string& o : {opt.output, opt.ply, opt.png})
    if (!o.empty()) outputs.push_back(o);
  for (const std::string& output : outputs)
    write_results(output_format(output), output, opt, map, results, queries ? &*queries : nullptr, lo, hi);
}

void write_results(const std::string& format, const std::string& output, const Options& opt, const SemanticMap& map,
                   const std::vector<ScoredCell>& results, const QuerySet* queries, float lo, float hi) {
  if (format == ".csv") {
    CsvWriter csv = queries ? CsvWriter({"rank", "x", "y", "z", "score", "count", "weight", "spread", "class", "confidence"})
                            : CsvWriter({"rank", "x", "y", "z", "score", "count", "weight", "spread"});
    for (std::size_t i = 0; i < results.size(); ++i) {
      const ScoredCell& r = results[i];
      const std::string rank = fmt::format("{}", i + 1), x = fmt::format("{:.3f}", r.position_world.x()),
                        y = fmt::format("{:.3f}", r.position_world.y()), z = fmt::format("{:.3f}", r.position_world.z()),
                        score = fmt::format("{:.6f}", r.score), count = fmt::format("{}", r.count),
                        weight = weight_text(r.stats), spread = spread_text(r.stats);
      if (queries)
        csv.row({rank, x, y, z, score, count, weight, spread, class_text(*queries, r), fmt::format("{:.4f}", r.confidence)});
      else
        csv.row({rank, x, y, z, score, count, weight, spread});
    }
    write_output_file(output, csv.text());
    fmt::print("CSV  {}: {} rows\n", output, results.size());
  } else if (format == ".png") {
    std::vector<ClassifiedCell> cells;
    for (const ScoredCell& c : results) cells.push_back({c.cell, c.position_world, c.count, {0, c.score, 0}, c.stats});
    sort_by_cell(cells);
    const BirdsEyeImage image = write_score_picture(output, map, cells, "cosine similarity", lo, hi);
    fmt::print("PNG  {} (+ .yaml): heat map of the {} results from above, {}x{} px, colour bar {:.3f}..{:.3f}\n",
               output, results.size(), image.rgb.cols, image.rgb.rows, lo, hi);
  } else {
    // Results coloured by score on the viridis ramp, in rank order.
    std::vector<ColouredVoxel> voxels;
    for (const ScoredCell& r : results)
      voxels.push_back({r.position_world.cast<float>(), score_colour(hi > lo ? (r.score - lo) / (hi - lo) : 1.f), r.count});
    if (format == ".ply") {
      write_ply(output, voxels, PlyEncoding::kBinaryLittleEndian);
      fmt::print("PLY  {}: {} voxels coloured by score ({:.3f}..{:.3f}, viridis)\n", output, voxels.size(), lo, hi);
    } else {
      HtmlViewerScene scene;
      scene.title = fmt::format("slamvdb query on {}", opt.source.name());
      scene.voxel_size = map.params().occupancy.voxel_size;
      for (const ColouredVoxel& v : voxels) scene.positions.push_back(v.position.cast<double>()), scene.colours.push_back(v.rgb);
      std::vector<Rgb8> stops;
      for (int i = 0; i <= 8; ++i) stops.push_back(score_colour(i / 8.0f));
      scene.colour_bar = HtmlViewerScene::ColourBar{"cosine similarity", lo, hi, stops};
      write_html_viewer(output, scene);
      fmt::print("HTML {}: {} voxels coloured by score, open it in a browser\n", output, voxels.size());
    }
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "query",
      "Ask a map: the voxels most similar to a query (text, a class of a query set, an image; several terms add up, "
      "--not terms subtract: the paper's Figure 6.2), or what the map holds at world points (--at)");
  opt->source.add_to(cmd);
  cmd->add_option("--text", opt->text, "A text query (repeatable: the terms add up)");
  cmd->add_option("--not", opt->not_text, "A text to subtract (repeatable)");
  cmd->add_option("--queries", opt->queries, "Query set file, for --class / --not-class, and to give every answer (--at points or similarity "
                  "results) its class and confidence")
      ->check(CLI::ExistingFile);
  cmd->add_option("--class", opt->classes, "A class of --queries as the query (repeatable)");
  cmd->add_option("--not-class", opt->not_classes, "A class of --queries to subtract (repeatable)");
  cmd->add_option("--image", opt->images, "An image as the query (repeatable)")->check(CLI::ExistingFile);
  cmd->add_option("--vector", opt->vectors,
                  "Query vectors from a float32/float16 .npy of shape (dim,) or (n, dim), each a positive term "
                  "(repeatable)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--not-vector", opt->not_vectors, "Query vectors (.npy) to subtract (repeatable)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--text-model", opt->text_model, "TorchScript CLIP text encoder (default: the SIMULATED one)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--image-model", opt->image_model,
                  "TorchScript CLIP image encoder (default: the SIMULATED one, which reads a 2D label image)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--sim-seed", opt->sim_seed, "Seed of the simulated encoders (as for `map`)")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_option("--sim-text-gap", opt->sim_text_gap, "SIMULATED text-image gap (see train-queries)")
      ->capture_default_str()
      ->check(kNonNegative);
  cmd->add_option("--top-k", opt->top_k, "Keep the K most similar voxels (0: all above --threshold)")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxCount));
  cmd->add_option("--threshold", opt->threshold, "Keep voxels whose cosine similarity is at least this")
      ->check(finite_range(-1.0, 1.0));
  opt->region.add_to(cmd, "voxels");
  cmd->add_option("--at", opt->at,
                  "A world point to look up (repeatable): x,y,z or \"x y z\", decimal numbers with '.' (no hex, nan, "
                  "inf or trailing text)");
  cmd->add_option("--at-csv", opt->at_csv,
                  "A file of world points to look up, one per line as for --at (fields separated by commas or by "
                  "blanks, numbers optionally in double quotes); a first line x,y,z that holds no number is a header, "
                  "a UTF-8 byte order mark and blank lines are skipped, any other bad line is an error naming it")
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", opt->output,
                  "Write the results; the format follows the extension: .csv (similarity: rank,x,y,z,score,count,weight,spread, "
                  "and class,confidence with --queries; "
                  "points: x,y,z,found,cell_x,cell_y,cell_z,count,class,score,margin,weight,spread,confidence; spread empty for "
                  "maps before format 3), .ply (voxels coloured by score), "
                  ".png (heat map from above with a colour bar, and a map_server .yaml beside it), .html (3D view)");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "With --queries and --at: let void classes win");
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "Accept an encoder or queries whose model id differs from the map's (the dimension is still checked)");
  cmd->add_option("--ply", opt->ply, "Also write the results as a PLY coloured by score");
  cmd->add_option("--png", opt->png, "Also write the heat map from above (PNG + map_server YAML)");
  add_option_checks(cmd, [opt] {
    output_format(opt->output);
    opt->region.region();
    opt->source.check(opt->region);
    if (!opt->ply.empty() && output_format(opt->ply) != ".ply") usage_error("--ply " + opt->ply + ": not a .ply name");
    if (!opt->png.empty() && output_format(opt->png) != ".png") usage_error("--png " + opt->png + ": not a .png name");
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("map", opt->source.map);
  io->input("--queries", opt->queries);
  io->input("--image", opt->images);
  io->input("--vector", opt->vectors);
  io->input("--not-vector", opt->not_vectors);
  io->input("--text-model", opt->text_model);
  io->input("--image-model", opt->image_model);
  io->input("--at-csv", opt->at_csv);
  const FilesOf files_of = [](const std::string& output) {
    return output_format(output) == ".png" ? png_with_yaml(output) : std::vector<std::filesystem::path>{output};
  };
  io->output("-o", opt->output, files_of);
  io->output("--ply", opt->ply);
  io->output("--png", opt->png, files_of);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_query
