// The server's request decoding (server/request_decoding.hpp). An input starting with '?' is the
// query string of GET /api/classes, /api/nav-grid and /api/points (name=value pairs split on '&', as the
// HTTP layer hands them over): decode_region_params, decode_classes_request and
// decode_nav_grid_request either refuse it with RequestError or give a region that is a finite
// box (min <= max) and/or a ball or cylinder of finite positive radius, a confidence in 0..1, a
// robot height in 0.1..100 and a positive finite resolution; decode_points_request (GET
// /api/points) a lod in 0..kPointsMaxLod, a limit in 1..kPointsMaxLimit and a query text of
// 1..max_text_bytes bytes, with a region only when one was asked. Anything else is a POST /api/query
// body for a 4-d map: decoded or refused; a decoded one must hold what the limits promise: at most
// max_terms terms, texts within max_text_bytes, vectors of the map's dimension with finite values,
// top_k within 1..max_top_k, images (base64 "image" terms, decode_base64) non-empty and never more
// bytes than three quarters of the body. decode_base64 alone on the input: bounded the same way.
#include <cmath>
#include <cstdlib>
#include <string>
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/server/points_answer.hpp"
#include "slamvdb/server/request_decoding.hpp"

namespace {

bool fuzz_region_ok(const slamvdb::QueryRegion& region) {
  if (!region.box && !region.near) return false;
  if (region.box && !(region.box->min().allFinite() && region.box->max().allFinite() &&
                      (region.box->min().array() <= region.box->max().array()).all()))
    return false;
  if (region.near && !(region.near->centre.allFinite() && std::isfinite(region.near->radius) && region.near->radius > 0))
    return false;
  return true;
}

void fuzz_get_params(std::string_view query) {
  slamvdb::NavGridParams p;
  slamvdb::PointsParams points;
  for (std::size_t start = 1; start <= query.size();) {
    const std::size_t end = std::min(query.find('&', start), query.size());
    const std::string_view pair = query.substr(start, end - start);
    const std::size_t eq = pair.find('=');
    const std::string name(pair.substr(0, eq));
    const std::string value(eq == std::string_view::npos ? std::string_view() : pair.substr(eq + 1));
    if (name == "bbox") p.region.bbox = value;
    if (name == "near") p.region.near = value;
    if (name == "radius") p.region.radius = value;
    if (name == "resolution") p.resolution = value;
    if (name == "format") p.format = value;
    if (name == "robot_height") p.robot_height = value;
    if (name == "min_confidence") p.min_confidence = value;
    if (name == "lod") points.lod = value;
    if (name == "limit") points.limit = value;
    if (name == "query") points.query = value;
    start = end + 1;
  }
  try {
    if (!fuzz_region_ok(slamvdb::decode_region_params(p.region, "GET /api/classes"))) std::abort();
  } catch (const slamvdb::Error&) {
  }
  try {
    const slamvdb::ClassesRequest c = slamvdb::decode_classes_request(p.region, p.min_confidence);
    if (!fuzz_region_ok(c.region) || !(c.min_confidence >= 0 && c.min_confidence <= 1)) std::abort();
  } catch (const slamvdb::Error&) {
  }
  try {
    const slamvdb::NavGridRequest g = slamvdb::decode_nav_grid_request(p);
    if (!fuzz_region_ok(g.region) || !(g.min_confidence >= 0 && g.min_confidence <= 1) ||
        !(g.robot_height >= 0.1 && g.robot_height <= 100) ||
        (g.resolution && !(std::isfinite(*g.resolution) && *g.resolution > 0)))
      std::abort();
  } catch (const slamvdb::Error&) {
  }
  points.region = p.region;
  slamvdb::ServerLimits limits;
  limits.max_text_bytes = 64;
  try {
    const slamvdb::PointsQuery q = slamvdb::decode_points_request(points, limits);
    const bool asked_region = points.region.bbox || points.region.near || points.region.radius;
    if (q.points.region.has_value() != asked_region || (q.points.region && !fuzz_region_ok(*q.points.region)) ||
        q.points.lod < 0 || q.points.lod > slamvdb::kPointsMaxLod || q.points.limit < 1 ||
        q.points.limit > slamvdb::kPointsMaxLimit || (q.text && (q.text->empty() || q.text->size() > limits.max_text_bytes)))
      std::abort();
  } catch (const slamvdb::Error&) {
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view body(reinterpret_cast<const char*>(data), size);
  if (!body.empty() && body.front() == '?') {
    fuzz_get_params(body);
    return 0;
  }
  if (const auto bytes = slamvdb::decode_base64(body); bytes && bytes->size() > body.size() * 3 / 4) std::abort();
  slamvdb::ServerLimits limits;
  limits.max_terms = 8;
  limits.max_text_bytes = 64;
  limits.max_top_k = 1000;
  try {
    const slamvdb::QueryRequest r = slamvdb::decode_query_request(body, 4, limits);
    const auto& t = r.terms;
    const std::size_t terms = r.images.size() + t.text.size() + t.not_text.size() + t.classes.size() +
                              t.not_classes.size() + t.vectors.size() + t.not_vectors.size();
    if (terms > limits.max_terms || (!t.has_positive() && r.images.empty())) std::abort();
    for (const std::string& image : r.images)
      if (image.empty() || image.size() > body.size() * 3 / 4) std::abort();
    for (const auto* texts : {&t.text, &t.not_text, &t.classes, &t.not_classes})
      for (const auto& s : *texts)
        if (s.empty() || s.size() > limits.max_text_bytes) std::abort();
    for (const auto* vectors : {&t.vectors, &t.not_vectors})
      for (const auto& v : *vectors)
        if (v.size() != 4 || !v.allFinite()) std::abort();
    if (r.search.top_k < 1 || r.search.top_k > limits.max_top_k) std::abort();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
