#pragma once
// The answers of the server's routes as JSON, without HTTP: what /api/query, /api/info and /healthz
// say, computed by the same library functions as the CLI (query/query_terms.hpp, map_query.hpp,
// io/map_info_json.hpp). The HTTP layer (http_server.cpp) only routes, limits and encodes.
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "slamvdb/io/query_image.hpp"
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
  std::vector<std::string> nav_costs;  // CLASS=COST overrides of the navigation grid (serve --cost)
  // The image encoder of "image" terms (null: they are refused), as `query --image` embeds a file,
  // and the most pixels an image may have.
  QueryImageEncoder* image = nullptr;
  std::int64_t max_image_pixels = ServerLimits{}.max_image_pixels;
};

// The region an answer was limited to, as the request gives it (null: the whole map).
nlohmann::json region_json(const std::optional<QueryRegion>& region);

// {"model_id", "simulated"} of the text encoder, null without one: part of every answer.
nlohmann::json encoder_json(const AnswerContext& context);

// POST /api/query: results ranked as `slamvdb query` ranks them (same search, same composite
// query), positions, scores, counts, statistics, and class + confidence with a query set.
// Throws RequestError for a question the map cannot answer (unknown text or class, ...).
nlohmann::json answer_query(const AnswerContext& context, const QueryRequest& request);

// POST /api/at: what the map holds at each point, the rows `query --at -o X.csv` writes (and the
// cell's mean embedding when asked), as the JSON text sent: written row by row, since a JSON object
// per row cost 4.7 us per point in nlohmann's DOM, three times the look-up itself (BM_ServeAtStages).
// The fields and their order are those of the DOM's text (keys sorted); invalid UTF-8 is replaced.
std::string answer_at(const AnswerContext& context, const AtRequest& request);

// GET /api/classes: the cells in the request's box classified against the server's query set, in
// cell order, each with the fields of `classify --bbox -o X.csv` (class_label, classified_row's
// numbers), and the summary `classify` prints (summarize_classes). Without a query set: 400; a
// region holding more than `max_cells` cells: 413 naming the count and the limit (counted before
// anything is classified).
nlohmann::json answer_classes(const AnswerContext& context, const ClassesRequest& request, std::size_t max_cells);

// GET /api/submaps: id, anchor, time range and counts of every submap (/api/info's "submaps").
nlohmann::json answer_submaps(const AnswerContext& context);

// GET /api/info: `slamvdb info --json --check` of the map, with the encoder.
nlohmann::json answer_info(const AnswerContext& context);

// The text encoder must embed into the map's space, as `query --text` checks (unless ignored).
void check_text_space(const TextEncoderInfo& encoder, const QuerySpace& space, bool ignore_model_id);

}  // namespace slamvdb
