// `slamvdb serve`: a saved map as a service over HTTP (issue 21), for planners, scripts and people.
// The map is loaded once and read through its global index; the text encoder (TorchScript or the
// SIMULATED one, said so in every answer) is loaded once, with a cache of text embeddings. Every
// answer comes from the same library functions as `query` and `info --json --check`.
// `serve --db URL` serves a fleet map instead (issue 24): every answer read from the database per
// request, as `query --db` and `classify --db` read it (fleet/fleet_map_service.hpp).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <thread>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "image_encoder_option.hpp"
#include "serve_access.hpp"
#include "text_encoder_option.hpp"
#include "session_option.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/fleet/fleet_map_service.hpp"
#include "slamvdb/server/http_server.hpp"

namespace slamvdb::cli::cmd_serve {
namespace {

struct Options {
  std::string map, db, bind = "127.0.0.1", queries, text_model, image_model, token_file, tls_cert, tls_key;
  int port = 8080;
  uint64_t sim_seed = 1;
  float sim_text_gap = 0.f;
  bool ignore_model_id = false, no_void_rule = false, no_text = false, no_image = false, insecure_no_auth = false;
  ServerLimits limits;
  std::vector<std::string> costs;  // NAME=COST of the navigation grid
  std::size_t ann_min_cells = 200000;  // maps this large get an ANN index for top-k queries
  int64_t time_budget_ms = 10000;      // ServerLimits::time_budget
  std::vector<std::string> sessions;   // --db: only these sessions' submaps
  std::size_t max_region_submaps = fleet::FleetServiceOptions{}.max_region_submaps;
};

// The map file loaded once, or the fleet map behind a connection string (checked here: reachable,
// its schema, a fleet in it), before anything listens.
std::shared_ptr<const MapService> open_service(const Options& opt) {
  if (!opt.db.empty()) {
    fleet::FleetServiceOptions options;
    options.sessions = opt.sessions;
    options.max_region_submaps = opt.max_region_submaps;
    return std::make_shared<fleet::FleetMapService>(opt.db, options);
  }
  // Below ann_min_cells exact scoring is fast enough (about 5 ms of a core per 100 k cells).
  const AnnOptions ann;
  return open_map_file_service(opt.map, &ann, opt.ann_min_cells);
}

void run(const Options& opt) {
  const std::string token = opt.token_file.empty() ? "" : read_token("--token", opt.token_file);
  const std::shared_ptr<const MapService> map = open_service(opt);
  std::unique_ptr<TextEmbeddingCache> text;
  if (!opt.no_text) {
    auto encoder = open_text_encoder(opt.text_model, map->space().dim, opt.sim_seed, opt.sim_text_gap);
    text = std::make_unique<TextEmbeddingCache>(std::move(encoder), opt.text_model.empty());
    check_text_space(text->info(), map->space(), opt.ignore_model_id);
  }
  std::shared_ptr<QueryImageEncoder> image;
  if (!opt.no_image) {
    image = open_image_encoder(opt.image_model, map->space().dim, opt.sim_seed);
    // An encoder of another space answers nothing meaningful. One asked for is an error; the
    // default SIMULATED one on a map of another space is left out (image questions are refused),
    // so that serving a CLIP map needs no new option.
    if (!opt.ignore_model_id && image->model_id() != map->space().model_id) {
      const std::string why = fmt::format("the image encoder embeds into '{}' but the map is in '{}'", image->model_id(),
                                          map->space().model_id);
      if (!opt.image_model.empty())
        throw Error(why + " (use the encoder the map was built with, or --ignore-model-id if they are the same space)");
      spdlog::warn("{}: image questions are refused (give --image-model)", why);
      image.reset();
    }
  }
  std::optional<QuerySet> queries;
  if (!opt.queries.empty()) {
    queries = load_query_set(opt.queries);
    check_compatible(*queries, map->space().dim, map->space().model_id,
                     opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch);
  }
  if (queries && !opt.costs.empty()) {
    try {
      nav_class_costs(queries->names, opt.costs);  // a bad --cost is said at start, not per request
    } catch (const Error& e) {
      throw Error(fmt::format("--cost: {}", e.what()));
    }
  }
  ServerOptions options;
  options.nav_costs = opt.costs;
  options.bind = opt.bind;
  options.port = opt.port;
  options.limits = opt.limits;
  options.limits.time_budget = std::chrono::milliseconds(opt.time_budget_ms);
  options.classify.void_to_second_best = !opt.no_void_rule;
  options.model_check = opt.ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch;
  options.queries_name = opt.queries;
  options.token = token;
  options.tls_cert = opt.tls_cert;
  options.tls_key = opt.tls_key;
  options.image_encoder = image;
  MapServer server(map, std::move(text), std::move(queries), options);

  // SIGINT / SIGTERM end the server cleanly (serve_access.hpp). Installed before the address is
  // printed: whoever reads it may signal at once.
  const StopSignal stop;
  const int port = server.bind();
  // A line of stdout names the address (with --port 0, the port the system chose); scripts and tests
  // read the port from it.
  const std::string address = fmt::format("{}://{}:{}/", opt.tls_cert.empty() ? "http" : "https",
                                          opt.bind.find(':') != std::string::npos ? "[" + opt.bind + "]" : opt.bind, port);
  // The fleet's URL after the address: the address is the line's first "://".
  if (opt.db.empty())
    fmt::print("serving {} on {} ({} semantic voxels)\n", opt.map, address, map->semantic_cells());
  else
    fmt::print("serving on {} the fleet map {} ({} semantic voxels in its catalog; questions need a region)\n",
               address, fleet::redact_connection_url(opt.db), map->semantic_cells());
  std::fflush(stdout);
  std::thread serving([&server] {
    server.run();
    StopSignal::notify();  // the server ended by itself: let the waiting thread go on
  });
  const int signal = stop.wait();
  server.stop();
  serving.join();
  spdlog::info("server stopped (signal {})", signal);
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "serve", "Serve a map over HTTP (read-only JSON API: /healthz, /metrics, /api/info, /api/submaps, /api/classes, /api/nav-grid, POST /api/query, POST /api/at; README \"slamvdb serve\")");
  cmd->add_option("map", opt->map, "Map file (.svdb); or --db")->check(CLI::ExistingFile);
  cmd->add_option("--db", opt->db,
                  "Serve a fleet map instead of a file: a libpq connection string (PostgreSQL + PostGIS, see `push`; "
                  "passwords from PGPASSFILE, not here). Every answer is read from the database per request; "
                  "POST /api/query needs a \"region\", GET /api/points a bbox or near (README \"Serving a fleet\")");
  add_session_option(cmd, opt->sessions, "With --db: only these sessions' submaps (repeatable; default: every session)");
  cmd->add_option("--max-region-submaps", opt->max_region_submaps,
                  "With --db: the most submaps POST /api/at, GET /api/points or /api/nav-grid read into memory for one "
                  "request; a region meeting more is refused with 413")
      ->capture_default_str()
      ->check(integer_range(1, 100000));
  cmd->add_option("--bind", opt->bind,
                  "Address to listen on; another than loopback (127.0.0.1, ::1, localhost) needs --token or "
                  "--insecure-no-auth")
      ->capture_default_str();
  cmd->add_option("--token", opt->token_file,
                  "File whose first line is a bearer token (16 characters or more) every route but /healthz requires: "
                  "\"Authorization: Bearer TOKEN\"")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--insecure-no-auth", opt->insecure_no_auth,
                "Serve another address than loopback without a token (anyone who reaches it reads the map)");
  cmd->add_option("--tls-cert", opt->tls_cert, "TLS: the certificate (chain) as PEM; needs --tls-key")
      ->check(CLI::ExistingFile);
  cmd->add_option("--tls-key", opt->tls_key, "TLS: the certificate's private key as PEM")->check(CLI::ExistingFile);
  cmd->add_option("--port", opt->port, "Port (0: a free one, printed in the line \"serving MAP on http://HOST:PORT/\")")
      ->capture_default_str()
      ->check(integer_range(0, 65535));
  cmd->add_option("--queries", opt->queries, "Query set file: class questions, and a class + confidence in every answer")
      ->check(CLI::ExistingFile);
  cmd->add_option("--text-model", opt->text_model, "TorchScript CLIP text encoder (default: the SIMULATED one)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--no-text", opt->no_text, "Load no text encoder (text questions are refused)");
  cmd->add_option("--image-model", opt->image_model,
                  "TorchScript CLIP image encoder of POST /api/query \"image\" (default: the SIMULATED one, which "
                  "reads a 2D label image), as query --image-model")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--no-image", opt->no_image, "Load no image encoder (image questions are refused)");
  cmd->add_option("--max-image-pixels", opt->limits.max_image_pixels,
                  "Most pixels of a query image (from its PNG / JPEG header, before decoding); more: 400")
      ->capture_default_str()
      ->check(integer_range(1, 100'000'000));
  cmd->add_option("--sim-seed", opt->sim_seed, "Seed of the simulated text encoder (as for `map`)")
      ->capture_default_str()
      ->check(integer_range(0, bounds::kMaxSeed));
  cmd->add_option("--sim-text-gap", opt->sim_text_gap, "SIMULATED text-image gap (see train-queries)")
      ->capture_default_str()
      ->check(finite_range(0.0, 1e6));
  cmd->add_flag("--ignore-model-id", opt->ignore_model_id,
                "Accept an encoder or queries whose model id differs from the map's (the dimension is still checked)");
  cmd->add_flag("--no-void-rule", opt->no_void_rule, "With --queries: let void classes win");
  cmd->add_option("--max-body", opt->limits.max_body_bytes, "Largest request body in bytes (larger: 413)")
      ->capture_default_str()
      ->check(integer_range(64, 64 << 20));
  cmd->add_option("--max-top-k", opt->limits.max_top_k, "Largest top_k of a query (and most results of one answer)")
      ->capture_default_str()
      ->check(integer_range(1, 1'000'000));
  cmd->add_option("--max-points", opt->limits.max_points, "Most points of one POST /api/at")
      ->capture_default_str()
      ->check(integer_range(1, 10'000'000));
  cmd->add_option("--max-cells", opt->limits.max_cells,
                  "Most cells of one GET /api/classes answer; a region holding more is refused with 413 naming the "
                  "count (split it into smaller boxes)")
      ->capture_default_str()
      ->check(integer_range(1, 100'000'000));
  cmd->add_option("--cost", opt->costs,
                  "GET /api/nav-grid: the cost of a class, CLASS=COST (as classify --cost: -1 unknown .. 100 lethal; "
                  "repeatable; defaults: the paper's terrain classes)");
  cmd->add_option("--max-concurrent", opt->limits.max_concurrent,
                  "Requests answered at once; more get 503 + Retry-After at once (/healthz and /metrics always answer)")
      ->capture_default_str()
      ->check(integer_range(1, 4096));
  cmd->add_option("--compute-slots", opt->limits.compute_slots,
                  "POST /api/query answers computed at once; the other admitted requests wait in arrival order; "
                  "0: the machine's hardware threads")
      ->capture_default_str()
      ->check(integer_range(0, 4096));
  cmd->add_option("--rate-limit", opt->limits.rate_per_client,
                  "Requests per second per client address; more get 429 + Retry-After (/healthz and /metrics are not "
                  "counted); 0: no limit")
      ->capture_default_str()
      ->check(finite_range(0.0, 1e6));
  cmd->add_option("--rate-burst", opt->limits.rate_burst, "Requests a client address may send at once (with --rate-limit)")
      ->capture_default_str()
      ->check(finite_range(1.0, 1e6));
  cmd->add_option("--time-budget", opt->time_budget_ms,
                  "Milliseconds one answer may take (query, at, classes, nav-grid, points); the work stops once they "
                  "have passed and the request gets 503 naming this option; 0: no limit")
      ->capture_default_str()
      ->check(integer_range(0, 86'400'000));
  cmd->add_option("--ann-min-cells", opt->ann_min_cells,
                  "Maps with at least this many semantic voxels get an approximate nearest-neighbour index for top-k "
                  "queries, built in the background after start (queries are exact until it is ready; answers say "
                  "\"exact\": false; a request may ask \"exact\": true); 0: always")
      ->capture_default_str()
      ->check(integer_range(0, 1'000'000'000));
  add_option_checks(cmd, [opt] {
    check_serve_access("--bind", opt->bind, !opt->token_file.empty(), opt->insecure_no_auth, "--token",
                       "--insecure-no-auth");
    if (opt->tls_cert.empty() != opt->tls_key.empty()) usage_error("--tls-cert and --tls-key go together");
    if (!opt->costs.empty() && opt->queries.empty()) usage_error("--cost needs --queries (the classes it gives costs to)");
    if (opt->map.empty() == opt->db.empty()) usage_error("give a map file or --db URL (one of the two)");
    if (opt->db.empty() && !opt->sessions.empty()) usage_error("--session goes with --db (a map file is served whole)");
  });
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("map", opt->map);
  io->input("--queries", opt->queries);
  io->input("--text-model", opt->text_model);
  io->input("--image-model", opt->image_model);
  io->input("--token", opt->token_file);
  io->input("--tls-cert", opt->tls_cert);
  io->input("--tls-key", opt->tls_key);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_serve
