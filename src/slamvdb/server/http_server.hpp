#pragma once
// `slamvdb serve`'s HTTP server (cpp-httplib): routes, JSON errors, limits, metrics, bearer
// tokens, optional TLS. Read-only: no route changes the map or a file. Bound to loopback by
// default; the command refuses other addresses without a token or --insecure-no-auth.
#include <memory>
#include <optional>
#include <string>

#include "slamvdb/server/map_answers.hpp"

namespace slamvdb {

struct ServerOptions {
  std::string bind = "127.0.0.1";
  int port = 8080;  // 0: an ephemeral port chosen by the system (tests), read back from bind()
  ServerLimits limits{};
  ClassifyOptions classify{};
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;
  std::string queries_name = "the server's query set";
  std::vector<std::string> nav_costs;  // CLASS=COST of the navigation grid (classify --cost's rules)
  // A bearer token every route but /healthz requires ("Authorization: Bearer TOKEN"), compared in
  // constant time; empty: none (the command allows that on loopback or with --insecure-no-auth).
  std::string token;
  // TLS (both or neither): PEM files of the certificate (chain) and its private key.
  std::string tls_cert, tls_key;
  // The encoder of POST /api/query "image" terms, chosen by the command as `query --image` chooses
  // it (a network, or the SIMULATED one on label images); null: image questions are refused.
  std::shared_ptr<QueryImageEncoder> image_encoder;
};

class MapServer {
 public:
  // `text` may be null (text questions are refused), `queries` too (class questions are refused).
  MapServer(std::shared_ptr<const MapService> map, std::unique_ptr<TextEmbeddingCache> text,
            std::optional<QuerySet> queries, ServerOptions options);
  ~MapServer();
  MapServer(const MapServer&) = delete;
  MapServer& operator=(const MapServer&) = delete;

  // Binds the address; returns the port (the chosen one for port 0). Throws Error naming the
  // address when it cannot be bound.
  int bind();
  // Serves until stop() (from another thread or a signal-waiting thread). Call after bind().
  void run();
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace slamvdb
