#pragma once
// GET /api/points?bbox=...&lod=...[&limit=N][&query=TEXT] without HTTP: the request's parameters
// decoded (400 naming the parameter), the points collected through MapService::points and encoded
// by encode_point_chunks (server/points_chunks.hpp). The HTTP layer only routes.
#include <optional>
#include <string>

#include "slamvdb/server/map_answers.hpp"
#include "slamvdb/server/points_chunks.hpp"
#include "slamvdb/server/request_decoding.hpp"

namespace slamvdb {

struct PointsParams {
  RegionParams region;  // bbox and/or near + radius, as /api/classes; none: the whole map
  std::optional<std::string> lod, limit, query, submap;
};

struct PointsQuery {
  PointsRequest points;
  std::optional<std::string> text;  // query=TEXT: each point's score against it instead of its class
};

// lod: an integer 0..kPointsMaxLod (default 0); limit: an integer 1..kPointsMaxLimit (default
// kPointsDefaultLimit); submap: a submap id (0..2^31-1; its chunks only); query: 1..limits.max_text_bytes bytes. Errors: RequestError 400 naming the parameter.
PointsQuery decode_points_request(const PointsParams& params, const ServerLimits& limits);

// The answer's bytes (application/octet-stream). Its meta JSON: values ("class", "score" or
// "none"), classes ([{name, rgb}] of the query set, value = index), score ({lo, hi, query} or
// null), points, chunks, lod, limit, voxel_size, region, encoder. Throws RequestError: 413 naming
// `limit` when the region holds more points than the limit at that lod, 400 naming `query` for a
// text the server cannot embed (or without a text encoder).
std::string answer_points(const AnswerContext& context, const PointsQuery& request);

}  // namespace slamvdb
