#pragma once
// Decoding of HTTP requests into the library's questions: small pure functions from text to
// structs, so that a libFuzzer harness (fuzz/fuzz_server_requests.cpp, next session) reaches them
// without a socket. Anything wrong is a RequestError naming the field, answered 400 (or the
// status it carries); nothing here trusts a size, a depth or a number from the request.
#include <chrono>
#include <cstddef>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/query/query_terms.hpp"

namespace slamvdb {

// The limits a request is held to (serve's options set them; README "slamvdb serve").
struct ServerLimits {
  // 4 MiB: 100 000 points of /api/at as JSON (about 20-30 bytes each), or many 512-d vectors.
  std::size_t max_body_bytes = 4 << 20;
  std::size_t max_top_k = 10000;         // results per answer
  std::size_t max_terms = 32;            // texts + classes + vectors of one question
  std::size_t max_text_bytes = 1000;     // one text term (CLIP reads 77 tokens anyway)
  std::size_t max_points = 100000;       // points of one POST /api/at
  // Requests answered at once; more are refused with 503 + Retry-After at once rather than queued
  // without bound (/healthz and /metrics are never refused, so monitoring sees a busy server).
  std::size_t max_concurrent = 32;
  // Answers of POST /api/query computed at once; the other admitted ones wait in arrival order
  // (server/compute_gate.hpp: fewer answers sharing the cores and caches, no unfair tail).
  // 0: the machine's hardware threads.
  std::size_t compute_slots = 0;
  // Cells one GET /api/classes answers (about 120 bytes of JSON each: 200 000 is ~25 MB); a region
  // holding more is refused with 413 naming the count and this limit (split the region instead).
  std::size_t max_cells = 200000;
  // Requests per second per client address (a token bucket holding `rate_burst`); more are refused
  // with 429 + Retry-After before any work (/healthz and /metrics are not counted). 0: no limit.
  double rate_per_client = 100;
  double rate_burst = 200;
  // Time one answer may take (--time-budget, in ms on the command line; 0: none). The scoring and
  // classifying loops check it between chunks and stop once it has passed (core/deadline.hpp); the
  // request is answered 503 naming the option, and counted (slamvdb_http_time_budget_exceeded_total).
  // 10 s: far above what a question costs on a map of a million cells (docs/serve-design.md).
  std::chrono::microseconds time_budget = std::chrono::seconds(10);
  // Pixels of one query image (POST /api/query "image"), read from its PNG / JPEG header before
  // anything is decoded (a small file can claim a huge image); more: 400 naming `image`.
  std::int64_t max_image_pixels = 4096 * 4096;
};

// A request the server refuses: HTTP status, the request field at fault ("" for the request as a
// whole) and a message for a person.
class RequestError : public Error {
 public:
  RequestError(int status, std::string field, const std::string& message)
      : Error(message), status_(status), field_(std::move(field)) {}
  int status() const { return status_; }
  const std::string& field() const { return field_; }

 private:
  int status_;
  std::string field_;
};

// The error body every refusal carries: {"error": {"message": ..., "field": ... or null}}.
nlohmann::json error_json(const std::string& message, const std::string& field);

// POST /api/query. Fields (docs/openapi.yaml): text, not, class, not_class (a string or an array of
// strings), vector, not_vector (an array of `dim` numbers or an array of such arrays), top_k
// (1..max_top_k, or 0 with a threshold: every cell at or above it, at most max_top_k), threshold
// (-1..1), exact (boolean), region ({"bbox": [xmin, ymin, zmin, xmax, ymax, zmax]} and/or
// {"near": [x, y] or [x, y, z], "radius": r}: query/query_region.hpp; errors name region.bbox,
// region.near or region.radius), image (a base64 PNG or JPEG, or an array of them: positive terms
// embedded as `query --image` embeds a file; "data:image/png;base64," before it is allowed).
// Unknown fields are refused (a typo must not pass as a default).
struct QueryRequest {
  QueryTerms terms;
  std::vector<std::string> images;  // the encoded bytes of each image term (PNG / JPEG, not yet checked)
  SearchOptions search = [] {  // the CLI's default: the top 100
    SearchOptions s;
    s.top_k = 100;
    return s;
  }();
  bool exact = false;       // exact scoring asked for (today every answer is exact)
  bool top_k_capped = false;  // top_k 0 + threshold: the answer holds at most max_top_k cells
};

QueryRequest decode_query_request(std::string_view body, int dim, const ServerLimits& limits);

// RFC 4648 base64 (standard alphabet; '=' padding optional, nothing after it; no whitespace), with
// an optional data URL prefix "data:<media type>;base64,". nullopt for anything else.
std::optional<std::string> decode_base64(std::string_view text);

// POST /api/at. Fields: points (an array of [x, y, z], finite numbers; 1..max_points of them),
// embedding (boolean, default false: the cell's count-weighted mean embedding in each answer).
struct AtRequest {
  std::vector<Vec3d> points;
  bool embedding = false;
};

AtRequest decode_at_request(std::string_view body, const ServerLimits& limits);

// GET /api/classes?bbox=xmin,ymin,zmin,xmax,ymax,zmax | near=x,y[,z]&radius=r [&min_confidence=c]:
// the region as `classify --bbox / --near --radius` takes it (query/query_region.hpp: a box, a
// ball or vertical cylinder, or both; at least one) and the confidence below which a cell's class
// is `uncertain` (0..1, default 0). Errors are 400 naming `bbox`, `near`, `radius` or
// `min_confidence`.
struct ClassesRequest {
  QueryRegion region;
  float min_confidence = 0.f;
};

// The parameters of a GET request by name (absent: nullopt), as the HTTP layer reads them.
struct RegionParams {
  std::optional<std::string> bbox, near, radius;
};

// The region of ?bbox= and/or ?near=&radius= (one of them required; `route` names the route in
// the message of a request without either).
QueryRegion decode_region_params(const RegionParams& params, const std::string& route);

ClassesRequest decode_classes_request(const RegionParams& region, const std::optional<std::string>& min_confidence);

// A confidence threshold parameter (0..1), 400 naming `field` otherwise.
float decode_confidence_param(const std::string& text, const std::string& field);

// GET /api/nav-grid?bbox=... | near=&radius= [&resolution=m] [&format=json|pgm|png|yaml]
// [&robot_height=m] [&min_confidence=c]: the grid `classify --bbox ... --grid` builds for the
// region. resolution, when given, must be a whole multiple of the map's cell (checked by the
// answer: NavGridOptions::resolution); robot_height 0.1..100 (default 1.5, as classify's --robot-height).
struct NavGridRequest {
  enum class Format { kJson, kPgm, kPng, kYaml };
  QueryRegion region;
  std::optional<double> resolution;
  Format format = Format::kJson;
  double robot_height = 1.5;
  float min_confidence = 0.f;
};

struct NavGridParams {
  RegionParams region;
  std::optional<std::string> resolution, format, robot_height, min_confidence;
};

NavGridRequest decode_nav_grid_request(const NavGridParams& params);

// A JSON object from a request body, refusing non-JSON, nesting deeper than `max_depth` (before a
// deep document is built) and anything but an object.
nlohmann::json parse_json_object(std::string_view body, int max_depth = 8);

}  // namespace slamvdb
