#include "slamvdb/server/http_server.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <atomic>
#include <chrono>
#include <thread>
#include <functional>
#include "slamvdb/server/httplib_include.hpp"

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

// A route's handler, with the library's refusals turned into JSON answers. Anything else thrown
// is a bug of ours: 500 with a generic message (logged, never a stack trace to the client).
using JsonRoute = std::function<void(const httplib::Request&, httplib::Response&)>;

httplib::Server::Handler guarded(JsonRoute route) {
  return [route = std::move(route)](const httplib::Request& req, httplib::Response& res) {
    try {
      route(req, res);
    } catch (const RequestError& e) {
      send_error(res, e.status(), e.what(), e.field());
    } catch (const std::exception& e) {
      spdlog::error("{} {}: {}", req.method, req.path, e.what());
      send_error(res, 500, "internal error (logged by the server)");
    }
  };
}

}  // namespace http_server_detail

struct MapServer::Impl {
  std::shared_ptr<const MapService> map;
  std::unique_ptr<TextEmbeddingCache> text;
  std::optional<QuerySet> queries;
  ServerOptions options;
  AnswerContext context;
  httplib::Server http;
  bool bound = false;
  std::atomic<bool> stopping{false}, running{false};  // see MapServer::stop

  void add_routes();
};

void MapServer::Impl::add_routes() {
  using namespace http_server_detail;
  // Every route with its one method; the other methods on a known path answer 405 (httplib alone
  // would say 404, which tells a client the path is wrong when the method is).
  struct Route {
    std::string path, method;
    JsonRoute handler;
  };
  const std::vector<Route> routes = {
      {"/healthz", "GET",
       [this](const httplib::Request&, httplib::Response& res) {
         send_json(res, 200, {{"status", "ok"}, {"semantic_cells", map->semantic_cells()}, {"encoder", encoder_json(context)}});
       }},
      {"/api/info", "GET",
       [this](const httplib::Request&, httplib::Response& res) { send_json(res, 200, answer_info(context)); }},
      {"/api/submaps", "GET",
       [this](const httplib::Request&, httplib::Response& res) { send_json(res, 200, answer_submaps(context)); }},
      {"/api/at", "POST",
       [this](const httplib::Request& req, httplib::Response& res) {
         send_json(res, 200, answer_at(context, decode_at_request(req.body, options.limits)));
       }},
      {"/api/query", "POST",
       [this](const httplib::Request& req, httplib::Response& res) {
         const QueryRequest request = decode_query_request(req.body, map->space().dim, options.limits);
         send_json(res, 200, answer_query(context, request));
       }},
  };
  for (const Route& r : routes) {
    const auto refuse = [path = r.path, method = r.method](const httplib::Request& req, httplib::Response& res) {
      res.set_header("Allow", method);
      send_error(res, 405, fmt::format("{} answers {} only, not {}", path, method, req.method));
    };
    const auto handler_for = [&](const std::string& method) {
      return method == r.method ? guarded(r.handler) : httplib::Server::Handler(refuse);
    };
    http.Get(r.path, handler_for("GET"));
    http.Post(r.path, handler_for("POST"));
    http.Put(r.path, handler_for("PUT"));
    http.Patch(r.path, handler_for("PATCH"));
    http.Delete(r.path, handler_for("DELETE"));
  }
  // Statuses httplib sets itself (404 no route, 413 body too large, 400 unreadable request): the
  // same JSON error body. Answers that already carry one are left as they are.
  http.set_error_handler(httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
    const std::string message = res.status == 404   ? fmt::format("no route {}", req.path)
                                : res.status == 413 ? "the request body is too large"
                                                    : fmt::format("HTTP {}", res.status);
    send_json(res, res.status, error_json(message, res.status == 413 ? "body" : ""));
    return httplib::Server::HandlerResponse::Handled;
  }));
  http.set_exception_handler([](const httplib::Request& req, httplib::Response& res, std::exception_ptr) {
    spdlog::error("{} {}: an exception escaped a route", req.method, req.path);
    send_json(res, 500, error_json("internal error (logged by the server)", ""));
  });
  http.set_payload_max_length(options.limits.max_body_bytes);
}

MapServer::MapServer(std::shared_ptr<const MapService> map, std::unique_ptr<TextEmbeddingCache> text,
                     std::optional<QuerySet> queries, ServerOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->map = std::move(map);
  impl_->text = std::move(text);
  impl_->queries = std::move(queries);
  impl_->options = std::move(options);
  AnswerContext& c = impl_->context;
  c.map = impl_->map.get();
  c.text = impl_->text.get();
  c.queries = impl_->queries ? &*impl_->queries : nullptr;
  c.queries_name = impl_->options.queries_name;
  c.classify = impl_->options.classify;
  c.model_check = impl_->options.model_check;
  impl_->add_routes();
}

MapServer::~MapServer() { stop(); }

int MapServer::bind() {
  const ServerOptions& o = impl_->options;
  int port = o.port;
  if (o.port == 0) {
    port = impl_->http.bind_to_any_port(o.bind);
    if (port < 0) throw Error(fmt::format("cannot bind {} on an ephemeral port", o.bind));
  } else if (!impl_->http.bind_to_port(o.bind, o.port)) {
    throw Error(fmt::format("cannot bind {}:{} (in use, or not an address of this machine)", o.bind, o.port));
  }
  impl_->bound = true;
  return port;
}

void MapServer::run() {
  if (!impl_->bound) throw Error("MapServer::run before bind");
  impl_->running = true;
  if (!impl_->stopping) impl_->http.listen_after_bind();
  impl_->running = false;
}

// httplib's stop() does nothing before its listen loop is up, so a stop that comes while run() is
// starting would be lost and run() would never return: stop() marks the server stopping (run()
// then does not start) or waits until the loop is up. Both flags are sequentially consistent, so
// one of the two threads always sees the other's flag.
void MapServer::stop() {
  impl_->stopping = true;
  while (impl_->running && !impl_->http.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  impl_->http.stop();
}

}  // namespace slamvdb
