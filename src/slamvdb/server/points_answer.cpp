#include "slamvdb/server/points_answer.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "slamvdb/core/point_text.hpp"

namespace slamvdb {

namespace points_answer_detail {

// One whole number in lo..hi, 400 naming `field` otherwise.
std::size_t whole_number_param(const std::string& text, const char* field, std::size_t lo, std::size_t hi) {
  std::vector<double> v;
  try {
    v = parse_numbers(text, field, 1, 1, "a whole number");
  } catch (const Error& e) {
    throw RequestError(400, field, e.what());
  }
  if (!(v[0] >= static_cast<double>(lo) && v[0] <= static_cast<double>(hi)) || v[0] != std::floor(v[0]))
    throw RequestError(400, field, fmt::format("{} {} is not a whole number in {}..{}", field, text, lo, hi));
  return static_cast<std::size_t>(v[0]);
}

}  // namespace points_answer_detail

PointsQuery decode_points_request(const PointsParams& params, const ServerLimits& limits) {
  using points_answer_detail::whole_number_param;
  PointsQuery r;
  if (params.region.bbox || params.region.near || params.region.radius)
    r.points.region = decode_region_params(params.region, "GET /api/points");
  if (params.lod) r.points.lod = static_cast<int>(whole_number_param(*params.lod, "lod", 0, kPointsMaxLod));
  if (params.limit) r.points.limit = whole_number_param(*params.limit, "limit", 1, kPointsMaxLimit);
  if (params.submap)
    r.points.submap = static_cast<int>(whole_number_param(*params.submap, "submap", 0, std::numeric_limits<int>::max()));
  if (params.query) {
    if (params.query->empty()) throw RequestError(400, "query", "query is empty (a text, e.g. query=tall%20grass)");
    if (params.query->size() > limits.max_text_bytes)
      throw RequestError(400, "query", fmt::format("query is {} bytes, over the limit of {}", params.query->size(),
                                                   limits.max_text_bytes));
    r.text = *params.query;
  }
  return r;
}

std::string answer_points(const AnswerContext& context, const PointsQuery& request) {
  PointValueSource source;
  source.queries = context.queries;
  source.classify = context.classify;
  source.model_check = context.model_check;
  if (request.text) {
    if (!context.text) throw RequestError(400, "query", "this server has no text encoder");
    // The question's vector as `query --text` and POST /api/query build it.
    TextEmbedder embed_text = [&](std::string_view text) -> Eigen::VectorXf { return context.text->embed(text); };
    QueryTerms terms;
    terms.text = {*request.text};
    QueryTermSources sources;
    sources.embed_text = &embed_text;
    try {
      source.query = build_query_vector(context.map->space(), terms, sources);
    } catch (const Error& e) {
      throw RequestError(400, "query", e.what());
    }
  }
  PointChunks chunks;
  try {
    chunks = context.map->points(request.points, source);
  } catch (const PointsOverBudget& e) {
    throw RequestError(413, "limit", e.what());
  } catch (const RequestError&) {
    throw;
  } catch (const DeadlineExceeded&) {
    throw;  // the time budget: 503 (http_server.cpp), not the 400 below
  } catch (const Error& e) {
    throw RequestError(400, "", e.what());  // the query set or question does not fit the map (its checks' message)
  }
  nlohmann::json classes = nullptr;
  if (context.queries) {
    classes = nlohmann::json::array();
    const QuerySet& q = *context.queries;
    for (std::size_t k = 0; k < q.names.size(); ++k) {
      const nlohmann::json rgb =
          k < q.colours.size() ? nlohmann::json({q.colours[k][0], q.colours[k][1], q.colours[k][2]}) : nlohmann::json();
      classes.push_back({{"name", q.names[k]}, {"rgb", rgb}});
    }
  }
  const char* values = chunks.values == PointChunks::Values::kScore   ? "score"
                       : chunks.values == PointChunks::Values::kClass ? "class"
                                                                      : "none";
  const nlohmann::json score =
      chunks.values == PointChunks::Values::kScore
          ? nlohmann::json({{"lo", chunks.score_lo}, {"hi", chunks.score_hi}, {"query", *request.text}})
          : nlohmann::json();
  const nlohmann::json meta = {{"values", values},
                               {"classes", classes},
                               {"score", score},
                               {"points", chunks.points},
                               {"chunks", chunks.chunks.size()},
                               {"lod", request.points.lod},
                               {"limit", request.points.limit},
                               {"voxel_size", chunks.voxel_size},
                               {"region", region_json(request.points.region)},
                               {"encoder", encoder_json(context)}};
  return encode_point_chunks(chunks, meta);
}

}  // namespace slamvdb
