#pragma once
// `map|slam --serve [ADDR:]PORT`: serve the map being built (live mode, issue 21) with serve's
// routes and page, through a LiveMapService over the mapper's map. The options are never recorded
// in the map (not configurable: the file is the same with or without them), and are checked before
// mapping starts with serve's own rules (serve_access.hpp). When mapping ends the server stops,
// or with --serve-linger serves the saved map until SIGINT / SIGTERM. `map --serve-wait-viewer`
// holds mapping once the first submap is finished until a viewer follows the map (a page opened
// at the address), so that it watches from the start.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "serve_access.hpp"
#include "text_encoder_option.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/server/http_server.hpp"
#include "slamvdb/server/live_map_service.hpp"

namespace slamvdb::cli {

struct LiveServeOptions {
  std::string address, token_file, queries;
  bool insecure_no_auth = false, linger = false;
  double refresh_seconds = 0.5;
  double wait_viewer_seconds = 0;  // 0: mapping never waits

  // `with_wait_viewer`: the command's pipeline calls PipelineOptions::first_submap_finished (map).
  void add_to(CLI::App* cmd, bool with_wait_viewer = false) {
    const auto live = [](CLI::Option* o) { return o->configurable(false)->group("Live view (--serve)"); };
    live(cmd->add_option("--serve", address,
                         "Serve the map being built over HTTP at [ADDR:]PORT (loopback when ADDR is not given; 0: a "
                         "free port, printed): serve's routes and page, finished submaps as they finish, loop "
                         "corrections as they move them, the active submap every --serve-refresh seconds; "
                         "README \"Live mode\""));
    live(cmd->add_option("--serve-token", token_file, "With --serve: a bearer token file (as serve --token)")
             ->check(CLI::ExistingFile));
    live(cmd->add_flag("--serve-insecure-no-auth", insecure_no_auth,
                       "With --serve on another address than loopback: no token (anyone who reaches it reads the map)"));
    live(cmd->add_option("--serve-queries", queries,
                         "With --serve: a query set (class questions, and the page's class colours)")
             ->check(CLI::ExistingFile));
    live(cmd->add_option("--serve-refresh", refresh_seconds,
                         "With --serve: seconds between looks at the map (events for viewers, the active submap)")
             ->capture_default_str()
             ->check(finite_range(0.05, 60)));
    live(cmd->add_flag("--serve-linger", linger,
                       "With --serve: after the map is saved, serve it until SIGINT / SIGTERM (default: stop)"));
    if (with_wait_viewer)
      live(cmd->add_option("--serve-wait-viewer", wait_viewer_seconds,
                           "With --serve: once the first submap is finished, hold mapping until a viewer follows the "
                           "map (the page open at the address, or any client of GET /api/events), at most this many "
                           "seconds (then mapping goes on; the log says whether a viewer came); with --realtime the replay's clock waits "
                           "too. The map is the same")
               ->check(finite_range(0.001, 86400)));
  }
  // Usage errors (exit 2) before any work.
  void check() const {
    const bool given = !token_file.empty() || !queries.empty() || insecure_no_auth || linger || wait_viewer_seconds > 0;
    if (address.empty()) {
      if (given)
        usage_error("--serve-token, --serve-queries, --serve-insecure-no-auth, --serve-linger and --serve-wait-viewer go "
                    "with --serve");
      return;
    }
    const auto [bind, port] = parse_serve_address("--serve", address);
    check_serve_access("--serve", bind, !token_file.empty(), insecure_no_auth, "--serve-token",
                       "--serve-insecure-no-auth");
  }
};

class LiveServer {
 public:
  // Binds and prints "serving SOURCE (live) on http://HOST:PORT/"; `simulated_text_seed`: the
  // SIMULATED text encoder's seed (the run's --sim-seed), none: no text questions.
  LiveServer(const LiveServeOptions& options, const std::string& source, int dim,
             std::optional<std::uint64_t> simulated_text_seed)
      : options_(options), map_(std::make_shared<LiveMapService>(source, dim, LiveMapOptions{options.refresh_seconds})) {
    const auto [bind, port] = parse_serve_address("--serve", options.address);
    ServerOptions server;
    server.bind = bind;
    server.port = port;
    server.token = options.token_file.empty() ? "" : read_token("--serve-token", options.token_file);
    // The map's model id is known once mapping starts; the dimension is checked.
    server.model_check = ModelIdCheck::kIgnore;
    server.queries_name = options.queries;
    std::unique_ptr<TextEmbeddingCache> text;
    if (simulated_text_seed)
      text = std::make_unique<TextEmbeddingCache>(open_text_encoder("", dim, *simulated_text_seed, 0.f), true);
    std::optional<QuerySet> queries;
    if (!options.queries.empty()) {
      queries = load_query_set(options.queries);
      check_compatible(*queries, dim, "", ModelIdCheck::kIgnore);
    }
    server_ = std::make_unique<MapServer>(map_, std::move(text), std::move(queries), server);
    const int bound = server_->bind();
    fmt::print("serving {} (live) on http://{}:{}/\n", source, bind.find(':') != std::string::npos ? "[" + bind + "]" : bind,
               bound);
    std::fflush(stdout);
    serving_ = std::thread([this] { server_->run(); });
  }
  ~LiveServer() { stop(); }
  LiveServer(const LiveServer&) = delete;
  LiveServer& operator=(const LiveServer&) = delete;

  // The mapper's map is read from map_started to map_ending.
  void watch(PipelineOptions& pipeline) {
    pipeline.map_started = [map = map_](const SemanticMap& m, std::function<std::vector<SubmapInfo>()> all_submaps) {
      map->attach(m, std::move(all_submaps));
    };
    pipeline.map_ending = [map = map_] { map->detach(); };
    if (options_.wait_viewer_seconds > 0)
      pipeline.first_submap_finished = [map = map_, seconds = options_.wait_viewer_seconds] {
        spdlog::info("first submap mapped: waiting up to {} s for a viewer (--serve-wait-viewer)", seconds);
        const auto start = std::chrono::steady_clock::now();
        if (map->wait_for_viewer(seconds))
          spdlog::info("a viewer follows the map (after {:.1f} s): mapping goes on",
                       std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
        else
          spdlog::warn("no viewer came within {} s (--serve-wait-viewer): mapping goes on without one", seconds);
      };
  }
  void progress(std::size_t done, std::size_t total) { map_->set_progress(done, total); }
  // After the map is saved: with --serve-linger serves it until SIGINT / SIGTERM; then stops.
  void finish(SemanticMap map) {
    if (options_.linger) {
      const StopSignal stop;
      map_->attach_final(std::make_shared<const SemanticMap>(std::move(map)));
      fmt::print("mapping done; serving the saved map until SIGINT / SIGTERM (--serve-linger)\n");
      std::fflush(stdout);
      spdlog::info("live server stopped (signal {})", stop.wait());
    }
    stop();
  }

 private:
  void stop() {
    if (!server_) return;
    server_->stop();
    if (serving_.joinable()) serving_.join();
    server_.reset();
  }

  LiveServeOptions options_;
  std::shared_ptr<LiveMapService> map_;
  std::unique_ptr<MapServer> server_;
  std::thread serving_;
};

}  // namespace slamvdb::cli
