#pragma once
// The answers of the server's routes as JSON, without HTTP: what /api/query, /api/info and /healthz
// say, computed by the same library functions as the CLI (query/query_terms.hpp, map_query.hpp,
// io/map_info_json.hpp). The HTTP layer (http_server.cpp) only routes, limits and encodes.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/server/map_service.hpp"
#include "slamvdb/server/request_decoding.hpp"
#include "slamvdb/server/text_embedding_cache.hpp"

namespace slamvdb {

// What the server answers with besides the map: the text encoder (null: text is refused), the
// query set (null: classes are refused, answers carry no class) and how to classify.
struct AnswerContext {
  const MapService* map = nullptr;
  TextEmbeddingCache* text = nullptr;
  const QuerySet* queries = nullptr;
  std::string queries_name = "the server's query set";
  ClassifyOptions classify{};
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;
};

// {"model_id", "simulated"} of the text encoder, null without one: part of every answer.
nlohmann::json encoder_json(const AnswerContext& context);

// POST /api/query: results ranked as `slamvdb query` ranks them (same search, same composite
// query), positions, scores, counts, statistics, and class + confidence with a query set.
// Throws RequestError for a question the map cannot answer (unknown text or class, ...).
nlohmann::json answer_query(const AnswerContext& context, const QueryRequest& request);

// POST /api/at: what the map holds at each point, the rows `query --at -o X.csv` writes (and the
// cell's mean embedding when asked).
nlohmann::json answer_at(const AnswerContext& context, const AtRequest& request);

// GET /api/submaps: id, anchor, time range and counts of every submap (/api/info's "submaps").
nlohmann::json answer_submaps(const AnswerContext& context);

// GET /api/info: `slamvdb info --json --check` of the map, with the encoder.
nlohmann::json answer_info(const AnswerContext& context);

// The text encoder must embed into the map's space, as `query --text` checks (unless ignored).
void check_text_space(const TextEncoderInfo& encoder, const QuerySpace& space, bool ignore_model_id);

}  // namespace slamvdb
