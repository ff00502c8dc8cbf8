#include "slamvdb/server/http_server.hpp"

#include <fmt/format.h>
#include <openssl/crypto.h>
#include <spdlog/spdlog.h>

#include <sys/socket.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <atomic>
#include <chrono>
#include <functional>
#include <limits>
#include <thread>

#include "slamvdb/core/deadline.hpp"
#include "slamvdb/server/client_rate_limit.hpp"
#include "slamvdb/server/compute_gate.hpp"
#include "slamvdb/server/httplib_include.hpp"
#include "slamvdb/server/nav_grid_answer.hpp"
#include "slamvdb/server/points_answer.hpp"
#include "slamvdb/server/server_metrics.hpp"
#include "slamvdb/server/web_assets.hpp"
#include "slamvdb/server/web_events.hpp"

namespace slamvdb {

namespace http_server_detail {

constexpr const char* kJson = "application/json";

void send_json(httplib::Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  // Text from the map or the request (class names, messages) that is not valid UTF-8 is replaced,
  // never a throw while answering.
  res.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), kJson);
}

void send_error(httplib::Response& res, int status, const std::string& message, const std::string& field = "") {
  send_json(res, status, error_json(message, field));
}

using JsonRoute = std::function<void(const httplib::Request&, httplib::Response&)>;

// A route's handler: admitted while fewer than `max_in_flight` requests are being answered (else
// 503 at once), the library's refusals turned into JSON answers, anything else thrown a bug of
// ours (500 with a generic message, logged, never a stack trace to the client), and every answer
// counted under the route's pattern.
httplib::Server::Handler guarded(ServerMetrics& metrics, std::string route, std::size_t max_in_flight,
                                 JsonRoute handler, ClientRateLimit* rate = nullptr,
                                 std::chrono::microseconds budget = std::chrono::microseconds(0)) {
  return [&metrics, route = std::move(route), max_in_flight, handler = std::move(handler), rate,
          budget](const httplib::Request& req, httplib::Response& res) {
    const auto start = std::chrono::steady_clock::now();
    // A client over its rate (client_rate_limit.hpp) is refused before it counts as in flight.
    if (const auto over = rate ? rate->admit(req.remote_addr) : ClientRateLimit::Decision{}; !over.admitted) {
      res.set_header("Retry-After", std::to_string(over.retry_after_seconds));
      send_error(res, 429, fmt::format("too many requests from {}: at most {:g} per second, {:g} at once "
                                       "(--rate-limit, --rate-burst); try again in {} s",
                                       req.remote_addr, rate->per_second(), rate->burst(), over.retry_after_seconds));
      metrics.record(route, res.status, 0.0);
      return;
    }
    {
      const ServerMetrics::InFlight in_flight(metrics);
      if (in_flight.count > max_in_flight) {
        res.set_header("Retry-After", "1");
        send_error(res, 503, fmt::format("busy: {} requests are being answered (--max-concurrent); try again",
                                         max_in_flight));
      } else {
        try {
          handler(req, res);
        } catch (const DeadlineExceeded& e) {
          // 503, not 504: 504 says a gateway got no timely answer from an upstream server; here the
          // origin server itself declines to spend more than its budget on one answer (the work is
          // stopped), a refusal of capacity as --max-concurrent's. No Retry-After: the same request
          // may exceed the budget again; a smaller one (region, top_k, points) fits.
          send_error(res, 503, fmt::format("{}: this server answers within {} ms (--time-budget); ask for less (a "
                                           "smaller region, top_k or fewer points) or try again when it is less busy",
                                           e.what(), std::chrono::duration_cast<std::chrono::milliseconds>(budget).count()));
          metrics.record_time_budget_exceeded(route);
        } catch (const RequestError& e) {
          send_error(res, e.status(), e.what(), e.field());
        } catch (const std::exception& e) {
          spdlog::error("{} {}: {}", req.method, req.path, e.what());
          send_error(res, 500, "internal error (logged by the server)");
        }
      }
    }
    metrics.record(route, res.status, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  };
}

// The query-string parameters of a GET route: any name the route does not take is refused (a typo
// must not pass as a default), 400 naming it.
class GetParams {
 public:
  GetParams(const httplib::Request& req, const std::string& route, std::initializer_list<std::string_view> known)
      : req_(req) {
    for (const auto& [name, value] : req.params)
      if (std::find(known.begin(), known.end(), name) == known.end()) {
        std::string names;
        for (const std::string_view k : known) names += (names.empty() ? "" : ", ") + std::string(k);
        throw RequestError(400, name, fmt::format("unknown parameter '{}' ({} takes {})", name, route, names));
      }
  }
  std::optional<std::string> get(const char* name) const {
    return req_.has_param(name) ? std::optional<std::string>(req_.get_param_value(name)) : std::nullopt;
  }
  RegionParams region() const { return {get("bbox"), get("near"), get("radius")}; }

 private:
  const httplib::Request& req_;
};

// "Authorization: Bearer TOKEN" against the token, in time independent of where they differ.
bool has_token(const httplib::Request& req, const std::string& token) {
  const std::string header = req.get_header_value("Authorization");
  const std::string prefix = "Bearer ";
  if (header.size() != prefix.size() + token.size() || header.compare(0, prefix.size(), prefix) != 0) return false;
  return CRYPTO_memcmp(header.data() + prefix.size(), token.data(), token.size()) == 0;
}

}  // namespace http_server_detail

struct MapServer::Impl {
  std::shared_ptr<const MapService> map;
  std::unique_ptr<TextEmbeddingCache> text;
  std::optional<QuerySet> queries;
  ServerOptions options;
  AnswerContext context;
  std::unique_ptr<httplib::Server> http;
  ServerMetrics metrics;
  bool bound = false;
  int listen_socket = -1;  // the socket httplib listens on (see add_routes)
  std::atomic<bool> stopping{false}, running{false};  // see MapServer::stop
  std::unique_ptr<MapEventStreams> events;  // GET /api/events (web_events.hpp)
  std::unique_ptr<ClientRateLimit> rate;  // per client address; null: no rate limit
  std::unique_ptr<ComputeGate> compute;  // POST /api/query's answers computing at once

  void add_routes();
  std::string metrics_text() const;
  // The context of one answer whose map-wide loops stop once the time budget has passed.
  AnswerContext within_budget() const {
    AnswerContext c = context;
    c.classify.deadline = Deadline::after(options.limits.time_budget);
    return c;
  }
};

std::string MapServer::Impl::metrics_text() const {
  std::map<std::string, std::pair<double, std::string>> gauges;
  gauges["slamvdb_map_semantic_cells"] = {static_cast<double>(map->semantic_cells()),
                                          "Cells of the global index that hold an embedding."};
  // A fleet map's submaps are in its database, read per request (/metrics does not ask it): none
  // in memory, and their count is not a gauge here.
  if (map->source_kind() != "fleet") {
    const nlohmann::json info = map->info();
    const double submaps = info.contains("submaps") ? static_cast<double>(info["submaps"].size()) : 0.0;
    gauges["slamvdb_map_submaps"] = {submaps, "Submaps of the map."};
    gauges["slamvdb_map_submaps_in_memory"] = {submaps, "Submaps held in memory (a saved map: all of them)."};
  } else {
    gauges["slamvdb_map_submaps_in_memory"] = {0.0, "Submaps held in memory (a fleet map: read per request)."};
  }
  if (compute) {
    gauges["slamvdb_query_compute_slots"] = {static_cast<double>(compute->slots()),
                                             "POST /api/query answers computed at once (the rest wait in arrival order)."};
    gauges["slamvdb_query_computing"] = {static_cast<double>(compute->computing()), "POST /api/query answers computing now."};
    gauges["slamvdb_query_waiting"] = {static_cast<double>(compute->waiting()),
                                       "POST /api/query answers waiting for a compute slot now."};
  }
  if (text) {
    const auto c = text->counts();
    gauges["slamvdb_text_cache_hits"] = {static_cast<double>(c.hits), "Text embeddings answered from the cache."};
    gauges["slamvdb_text_cache_misses"] = {static_cast<double>(c.misses), "Text embeddings computed by the encoder."};
    gauges["slamvdb_text_cache_entries"] = {static_cast<double>(c.size), "Text embeddings in the cache."};
  }
  return metrics.text(gauges);
}

void MapServer::Impl::add_routes() {
  using namespace http_server_detail;
  constexpr std::size_t kAlways = std::numeric_limits<std::size_t>::max();  // monitoring: never refused
  const std::size_t limit = options.limits.max_concurrent;
  events = std::make_unique<MapEventStreams>(*map, stopping);
  if (options.limits.rate_per_client > 0)
    rate = std::make_unique<ClientRateLimit>(options.limits.rate_per_client, options.limits.rate_burst);
  compute = std::make_unique<ComputeGate>(options.limits.compute_slots);
  // Every route with its one method; the other methods on a known path answer 405 (httplib alone
  // would say 404, which tells a client the path is wrong when the method is).
  struct Route {
    std::string path, method;
    std::size_t max_in_flight;
    JsonRoute handler;
  };
  const std::vector<Route> routes = {
      {"/healthz", "GET", kAlways,
       [this](const httplib::Request&, httplib::Response& res) {
         send_json(res, 200, {{"status", "ok"}, {"semantic_cells", map->semantic_cells()}, {"encoder", encoder_json(context)},
                              {"index", map->index_state()}});
       }},
      {"/metrics", "GET", kAlways,
       [this](const httplib::Request&, httplib::Response& res) {
         res.set_content(metrics_text(), "text/plain; version=0.0.4; charset=utf-8");
       }},
      {"/api/info", "GET", limit,
       [this](const httplib::Request&, httplib::Response& res) { send_json(res, 200, answer_info(context)); }},
      {"/api/submaps", "GET", limit,
       [this](const httplib::Request&, httplib::Response& res) { send_json(res, 200, answer_submaps(context)); }},
      {"/api/at", "POST", limit,
       [this](const httplib::Request& req, httplib::Response& res) {
         const AtRequest request = decode_at_request(req.body, options.limits);
         res.status = 200;
         res.set_content(answer_at(within_budget(), request), kJson);
       }},
      {"/api/classes", "GET", limit,
       [this](const httplib::Request& req, httplib::Response& res) {
         const GetParams params(req, "GET /api/classes", {"bbox", "near", "radius", "min_confidence"});
         const ClassesRequest request = decode_classes_request(params.region(), params.get("min_confidence"));
         send_json(res, 200, answer_classes(within_budget(), request, options.limits.max_cells));
       }},
      {"/api/nav-grid", "GET", limit,
       [this](const httplib::Request& req, httplib::Response& res) {
         const GetParams params(req, "GET /api/nav-grid",
                                {"bbox", "near", "radius", "resolution", "format", "robot_height", "min_confidence"});
         const NavGridRequest request = decode_nav_grid_request({params.region(), params.get("resolution"),
                                                                 params.get("format"), params.get("robot_height"),
                                                                 params.get("min_confidence")});
         NavGridAnswer answer = answer_nav_grid(within_budget(), request, options.limits.max_cells);
         res.status = 200;
         res.set_content(std::move(answer.body), answer.content_type);
       }},
      // The page and its script, from the bundle compiled in (web_assets.hpp): no path reaches a file.
      {"/", "GET", limit,
       [](const httplib::Request& req, httplib::Response& res) {
         const WebAsset asset = web_asset(req.path);
         res.set_content(std::string(asset.body), std::string(asset.content_type));
       }},
      {"/assets/serve.js", "GET", limit,
       [](const httplib::Request& req, httplib::Response& res) {
         const WebAsset asset = web_asset(req.path);
         res.set_content(std::string(asset.body), std::string(asset.content_type));
       }},
      {"/api/events", "GET", limit,
       [this](const httplib::Request& req, httplib::Response& res) {
         const GetParams params(req, "GET /api/events", {});
         events->open(res);
       }},
      {"/api/points", "GET", limit,
       [this](const httplib::Request& req, httplib::Response& res) {
         const GetParams params(req, "GET /api/points", {"bbox", "near", "radius", "lod", "limit", "query", "submap"});
         const PointsQuery request = decode_points_request(
             {params.region(), params.get("lod"), params.get("limit"), params.get("query"), params.get("submap")},
             options.limits);
         res.status = 200;
         res.set_content(answer_points(within_budget(), request), "application/octet-stream");
       }},
      {"/api/query", "POST", limit,
       [this](const httplib::Request& req, httplib::Response& res) {
         QueryRequest request = decode_query_request(req.body, map->space().dim, options.limits);
         request.search.deadline = Deadline::after(options.limits.time_budget);
         const ComputeGate::Pass computing = compute->enter(request.search.deadline);
         send_json(res, 200, answer_query(context, request));
       }},
  };
  for (const Route& r : routes) {
    const JsonRoute refuse = [path = r.path, method = r.method](const httplib::Request& req, httplib::Response& res) {
      res.set_header("Allow", method);
      send_error(res, 405, fmt::format("{} answers {} only, not {}", path, method, req.method));
    };
    const auto handler_for = [&](const std::string& method) {
      return guarded(metrics, r.path, method == r.method ? r.max_in_flight : kAlways,
                     method == r.method ? r.handler : refuse,
                     method == r.method && r.max_in_flight != kAlways ? rate.get() : nullptr, options.limits.time_budget);
    };
    http->Get(r.path, handler_for("GET"));
    http->Post(r.path, handler_for("POST"));
    http->Put(r.path, handler_for("PUT"));
    http->Patch(r.path, handler_for("PATCH"));
    http->Delete(r.path, handler_for("DELETE"));
  }
  // A bearer token, when set, guards every route but /healthz (probes need no secret; it tells
  // only that the server is up). Checked before routing, so no route runs for a stranger.
  if (!options.token.empty())
    http->set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      if (req.path == "/healthz" || has_token(req, options.token)) return httplib::Server::HandlerResponse::Unhandled;
      res.set_header("WWW-Authenticate", "Bearer");
      send_error(res, 401, "this server needs \"Authorization: Bearer TOKEN\" (the token of its --token file)");
      metrics.record("unauthorized", 401, 0.0);
      return httplib::Server::HandlerResponse::Handled;
    });
  // Statuses httplib sets itself (404 no route, 413 body too large, 400 unreadable request): the
  // same JSON error body, counted under "unmatched". Answers that already carry one are left.
  http->set_error_handler(
      httplib::Server::HandlerWithResponse([this](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        const std::string message = res.status == 404   ? fmt::format("no route {}", req.path)
                                    : res.status == 413 ? "the request body is too large (--max-body)"
                                                        : fmt::format("HTTP {}", res.status);
        send_json(res, res.status, error_json(message, res.status == 413 ? "body" : ""));
        metrics.record("unmatched", res.status, 0.0);
        return httplib::Server::HandlerResponse::Handled;
      }));
  http->set_exception_handler([](const httplib::Request& req, httplib::Response& res, std::exception_ptr) {
    spdlog::error("{} {}: an exception escaped a route", req.method, req.path);
    send_json(res, 500, error_json("internal error (logged by the server)", ""));
  });
  http->set_payload_max_length(options.limits.max_body_bytes);
  // Workers: the admission limit plus room for monitoring and refusals, so that the limit, not
  // the pool, decides who waits (httplib's own pool is sized for the CPU and queues without bound).
  const std::size_t workers = std::min<std::size_t>(limit, 256) + 4;
  http->new_task_queue = [workers] { return new httplib::ThreadPool(workers); };
  // Debian's httplib listens with a backlog of 5 (CPPHTTPLIB_LISTEN_BACKLOG, compiled into the
  // library): when more clients connect at once, the kernel drops their SYN and they retry after
  // a second (ServeLoad's p99 was that second: TcpExtListenOverflows counted the drops). The
  // socket is remembered here (with httplib's own options) and bind() listens on it again with a
  // larger backlog (Linux changes the backlog of a listening socket).
  http->set_socket_options([this](socket_t sock) {
    httplib::default_socket_options(sock);
    listen_socket = sock;
  });
}

MapServer::MapServer(std::shared_ptr<const MapService> map, std::unique_ptr<TextEmbeddingCache> text,
                     std::optional<QuerySet> queries, ServerOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->map = std::move(map);
  impl_->text = std::move(text);
  impl_->queries = std::move(queries);
  impl_->options = std::move(options);
  const ServerOptions& o = impl_->options;
  if (o.tls_cert.empty() != o.tls_key.empty()) throw Error("TLS needs both a certificate and its key");
  if (!o.tls_cert.empty()) {
    auto tls = std::make_unique<httplib::SSLServer>(o.tls_cert.c_str(), o.tls_key.c_str());
    if (!tls->is_valid())
      throw Error(fmt::format("cannot use the TLS certificate {} with the key {} (PEM files that belong together?)",
                              o.tls_cert, o.tls_key));
    impl_->http = std::move(tls);
  } else {
    impl_->http = std::make_unique<httplib::Server>();
  }
  AnswerContext& c = impl_->context;
  c.map = impl_->map.get();
  c.text = impl_->text.get();
  c.queries = impl_->queries ? &*impl_->queries : nullptr;
  c.queries_name = o.queries_name;
  c.nav_costs = o.nav_costs;
  c.classify = o.classify;
  c.model_check = o.model_check;
  c.image = o.image_encoder.get();
  c.max_image_pixels = o.limits.max_image_pixels;
  impl_->add_routes();
}

MapServer::~MapServer() { stop(); }

int MapServer::bind() {
  const ServerOptions& o = impl_->options;
  int port = o.port;
  if (o.port == 0) {
    port = impl_->http->bind_to_any_port(o.bind);
    if (port < 0) throw Error(fmt::format("cannot bind {} on an ephemeral port", o.bind));
  } else if (!impl_->http->bind_to_port(o.bind, o.port)) {
    throw Error(fmt::format("cannot bind {}:{} (in use, or not an address of this machine)", o.bind, o.port));
  }
  constexpr int kListenBacklog = 1024;  // bounded still (and by net.core.somaxconn)
  if (impl_->listen_socket >= 0 && ::listen(impl_->listen_socket, kListenBacklog) != 0)
    spdlog::warn("cannot raise the listen backlog ({}): clients beyond 5 connecting at once wait 1 s", std::strerror(errno));
  impl_->bound = true;
  return port;
}

void MapServer::run() {
  if (!impl_->bound) throw Error("MapServer::run before bind");
  impl_->running = true;
  if (!impl_->stopping) impl_->http->listen_after_bind();
  impl_->running = false;
}

// httplib's stop() does nothing before its listen loop is up, so a stop that comes while run() is
// starting would be lost and run() would never return: stop() marks the server stopping (run()
// then does not start) or waits until the loop is up. Both flags are sequentially consistent, so
// one of the two threads always sees the other's flag.
void MapServer::stop() {
  impl_->stopping = true;
  while (impl_->running && !impl_->http->is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  impl_->http->stop();
}

}  // namespace slamvdb
