#include "slamvdb/server/map_answers.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>

#include "slamvdb/query/class_summary.hpp"

namespace slamvdb {

nlohmann::json encoder_json(const AnswerContext& context) {
  if (!context.text) return nullptr;
  return {{"model_id", context.text->info().model_id}, {"simulated", context.text->info().simulated}};
}

void check_text_space(const TextEncoderInfo& encoder, const QuerySpace& space, bool ignore_model_id) {
  if (ignore_model_id || encoder.model_id == space.model_id) return;
  throw Error(fmt::format("the text encoder embeds into '{}' but the map is in '{}' (use the encoder the map was "
                          "built with, or --ignore-model-id if they are the same space)",
                          encoder.model_id, space.model_id));
}

namespace map_answers_detail {

// Which request field an Error of the library is about, for the 400 answer.
std::string field_of_terms(const QueryTerms& terms) {
  if (terms.uses_classes()) return "class";
  if (terms.uses_text()) return "text";
  return "vector";
}

// The region an answer was limited to, as the request gives it (null: the whole map).
nlohmann::json region_json(const std::optional<QueryRegion>& region) {
  if (!region) return nullptr;
  nlohmann::json j = nlohmann::json::object();
  if (region->box) {
    const Vec3d& lo = region->box->min();
    const Vec3d& hi = region->box->max();
    j["bbox"] = {lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z()};
  }
  if (region->near) {
    const Vec3d& c = region->near->centre;
    j["near"] = region->near->horizontal ? nlohmann::json({c.x(), c.y()}) : nlohmann::json({c.x(), c.y(), c.z()});
    j["radius"] = region->near->radius;
  }
  return j;
}

// The submaps an answer may have left out: those out of memory when it began (`before`) or when it
// ended (live mode: a submap can leave or come back while a question is answered).
std::vector<int> submaps_not_searched(const MapService& map, std::vector<int> before) {
  std::vector<int> after = map.submaps_out_of_memory(), both;
  std::set_union(before.begin(), before.end(), after.begin(), after.end(), std::back_inserter(both));
  return both;
}

}  // namespace map_answers_detail

nlohmann::json answer_query(const AnswerContext& context, const QueryRequest& request) {
  const QuerySpace space = context.map->space();
  if (request.terms.uses_text() && !context.text)
    throw RequestError(400, "text", "this server has no text encoder");
  if (request.terms.uses_classes() && !context.queries)
    throw RequestError(400, "class", "this server has no query set (start it with --queries)");
  TextEmbedder embed_text = [&](std::string_view text) -> Eigen::VectorXf {
    try {
      return context.text->embed(text);
    } catch (const Error& e) {
      throw RequestError(400, "text", e.what());
    }
  };
  // Images are positive vector terms, embedded as `query --image` embeds a file (io/query_image.hpp).
  QueryTerms terms = request.terms;
  if (!request.images.empty() && !context.image)
    throw RequestError(400, "image", "this server has no image encoder");
  for (std::size_t i = 0; i < request.images.size(); ++i) {
    std::vector<float> v;
    try {
      v = context.image->embed_bytes(request.images[i], fmt::format("'image'[{}]", i), context.max_image_pixels);
    } catch (const Error& e) {
      throw RequestError(400, "image", e.what());  // not a PNG / JPEG, damaged, too many pixels, not label ids
    }
    terms.vectors.push_back(Eigen::Map<const Eigen::VectorXf>(v.data(), static_cast<Eigen::Index>(v.size())));
  }
  QueryTermSources sources;
  sources.embed_text = context.text ? &embed_text : nullptr;
  sources.queries = context.queries;
  sources.queries_name = context.queries_name;
  sources.model_check = context.model_check;
  Eigen::VectorXf q;
  try {
    q = build_query_vector(space, terms, sources);
  } catch (const RequestError&) {
    throw;
  } catch (const Error& e) {
    const bool images_only = !request.images.empty() && !request.terms.uses_classes() && !request.terms.uses_text();
    throw RequestError(400, images_only ? "image" : map_answers_detail::field_of_terms(request.terms), e.what());
  }
  // `not` terms move the question away from the cells the index groups: they are scored exactly.
  const bool exact = request.exact || !request.terms.not_text.empty() || !request.terms.not_classes.empty() ||
                     !request.terms.not_vectors.empty();
  std::vector<int> not_searched = context.map->submaps_out_of_memory();
  MapService::SearchAnswer found =
      context.map->search_and_classify(std::span<const float>(q.data(), static_cast<std::size_t>(q.size())),
                                       request.search, exact, context.queries, context.classify, context.model_check);
  not_searched = map_answers_detail::submaps_not_searched(*context.map, std::move(not_searched));
  std::vector<ScoredCell>& results = found.cells;
  nlohmann::json rows = nlohmann::json::array();
  for (std::size_t i = 0; i < results.size(); ++i) {
    const ScoredCell& r = results[i];
    nlohmann::json row = {{"rank", i + 1},
                          {"position", {r.position_world.x(), r.position_world.y(), r.position_world.z()}},
                          {"score", r.score},
                          {"count", r.count},
                          {"weight", r.stats.weight},
                          // S/W as the CLI's CSV writes it; null where the map does not know it.
                          {"spread", r.stats.known() && r.stats.weight > 0 ? nlohmann::json(r.stats.spread / r.stats.weight)
                                                                            : nlohmann::json()}};
    if (context.queries) {
      const bool has_class = r.match && r.match->class_index != kNoClass;
      row["class"] = has_class ? nlohmann::json(context.queries->names[static_cast<std::size_t>(r.match->class_index)])
                               : nlohmann::json();
      row["confidence"] = r.confidence;
    }
    rows.push_back(std::move(row));
  }
  nlohmann::json answer = {{"encoder", encoder_json(context)},
          {"served_from", context.map->source_kind()},
          {"semantic_cells", context.map->semantic_cells()},
          {"top_k", request.top_k_capped ? 0 : request.search.top_k},
          {"threshold", std::isfinite(request.search.threshold) ? nlohmann::json(request.search.threshold) : nlohmann::json()},
          {"exact", !found.approximate},  // false: the cells an ANN index proposed, scored exactly
          {"truncated", request.top_k_capped && results.size() >= request.search.top_k},
          {"region", map_answers_detail::region_json(request.search.region)},
          {"count", results.size()},
          {"results", std::move(rows)},
          {"submaps_not_searched", std::move(not_searched)}};
  // Which encoder embedded the images (SIMULATED: from a 2D label image), as "encoder" says for text.
  if (!request.images.empty())
    answer["image_encoder"] = {{"model_id", context.image->model_id()}, {"simulated", context.image->reads_labels()}};
  return answer;
}

namespace {

// A number as nlohmann's dump writes a double (floats widened first, as the DOM stores them): the
// shortest text that reads back as the same double, "null" when not finite. fmt's "{}" gives the
// same digits; an integral value is written without nlohmann's ".0" (the same JSON number).
void append_number(fmt::memory_buffer& out, double x) {
  if (std::isfinite(x)) {
    fmt::format_to(std::back_inserter(out), "{}", x);
  } else {
    out.append(std::string_view("null"));
  }
}

void append_text(fmt::memory_buffer& out, const std::string& text) {
  const std::string quoted = nlohmann::json(text).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  out.append(quoted);
}

void append_vec3(fmt::memory_buffer& out, const Vec3d& v) {
  out.push_back('[');
  append_number(out, v.x());
  out.push_back(',');
  append_number(out, v.y());
  out.push_back(',');
  append_number(out, v.z());
  out.push_back(']');
}

// One row of POST /api/at, keys in sorted order as the DOM wrote them.
void append_at_row(fmt::memory_buffer& out, const PointQuery& a, const std::vector<std::string>& class_texts,
                   bool with_embedding) {
  const auto key = [&out](std::string_view k) {
    out.push_back('"');
    out.append(k);
    out.append(std::string_view("\":"));
  };
  const auto null = [&out] { out.append(std::string_view("null")); };
  const bool has_class = a.match && a.match->class_index != kNoClass;
  out.push_back('{');
  key("cell");
  a.found ? append_vec3(out, a.cell_centre) : null();
  out.push_back(',');
  key("class");
  has_class ? out.append(class_texts[static_cast<std::size_t>(a.match->class_index)]) : null();
  out.push_back(',');
  key("confidence");
  a.match ? append_number(out, a.confidence) : null();
  out.push_back(',');
  key("count");
  fmt::format_to(std::back_inserter(out), "{}", a.count);
  out.push_back(',');
  if (with_embedding) {
    key("embedding");
    if (a.found) {
      out.push_back('[');
      for (std::size_t k = 0; k < a.embedding.size(); ++k) {
        if (k) out.push_back(',');
        append_number(out, a.embedding[k]);
      }
      out.push_back(']');
    } else {
      null();
    }
    out.push_back(',');
  }
  key("found");
  out.append(std::string_view(a.found ? "true" : "false"));
  out.push_back(',');
  key("last_session");
  a.found ? append_text(out, a.last_session_name) : null();
  out.push_back(',');
  key("margin");
  a.match ? append_number(out, a.match->margin) : null();
  out.push_back(',');
  key("point");
  append_vec3(out, a.point_world);
  out.push_back(',');
  key("score");
  a.match ? append_number(out, a.match->score) : null();
  out.push_back(',');
  key("spread");
  a.found && a.stats.known() && a.stats.weight > 0 ? append_number(out, a.stats.spread / a.stats.weight) : null();
  out.push_back(',');
  key("weight");
  a.found ? append_number(out, a.stats.weight) : null();
  out.push_back('}');
}

}  // namespace

std::string answer_at(const AnswerContext& context, const AtRequest& request) {
  const std::vector<int> before = context.map->submaps_out_of_memory();
  const std::vector<PointQuery> answers =
      context.map->at(request.points, context.queries, context.classify, context.model_check, request.embedding);
  const std::vector<int> not_searched = map_answers_detail::submaps_not_searched(*context.map, before);
  std::vector<std::string> class_texts;  // each class name quoted and escaped once
  if (context.queries)
    for (const std::string& name : context.queries->names) class_texts.push_back(nlohmann::json(name).dump(
        -1, ' ', false, nlohmann::json::error_handler_t::replace));
  const std::size_t found =
      static_cast<std::size_t>(std::count_if(answers.begin(), answers.end(), [](const PointQuery& a) { return a.found; }));
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out), R"({{"count":{},"encoder":{},"found":{},"results":[)", answers.size(),
                 encoder_json(context).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace), found);
  for (std::size_t i = 0; i < answers.size(); ++i) {
    if (i) out.push_back(',');
    append_at_row(out, answers[i], class_texts, request.embedding);
  }
  fmt::format_to(std::back_inserter(out), R"(],"submaps_not_searched":[{}]}})", fmt::join(not_searched, ","));
  return fmt::to_string(out);
}

nlohmann::json answer_classes(const AnswerContext& context, const ClassesRequest& request, std::size_t max_cells) {
  if (!context.queries)
    throw RequestError(400, "", "GET /api/classes needs a query set: this server was started without --queries");
  // Refused before classifying: a city-sized region must cost a count, not a classification.
  if (const std::size_t n = context.map->region_cells(request.region); n > max_cells)
    throw RequestError(413, request.region.box ? "bbox" : "radius",
                       fmt::format("the region holds {}{} semantic cells; GET /api/classes answers at most {} (the "
                                   "server's --max-cells): split the region into smaller boxes",
                                   context.map->source_kind() == "fleet" ? "up to " : "", n, max_cells));
  const QuerySet& queries = *context.queries;
  std::vector<ClassifiedCell> cells;
  std::vector<int> not_searched = context.map->submaps_out_of_memory();
  try {
    cells = context.map->classes(queries, request.region, context.classify, context.model_check);
  } catch (const RequestError&) {
    throw;
  } catch (const DeadlineExceeded&) {
    throw;  // the time budget: 503 (http_server.cpp), not the 400 below
  } catch (const Error& e) {
    throw RequestError(400, "", e.what());  // the query set does not fit the map (its checks' message)
  }
  not_searched = map_answers_detail::submaps_not_searched(*context.map, std::move(not_searched));
  const ClassSummary summary = summarize_classes(cells, queries, request.min_confidence);
  nlohmann::json classes = nlohmann::json::array();
  for (std::size_t k = 0; k < summary.per_class.size(); ++k)
    classes.push_back({{"name", queries.names[k]}, {"voxels", summary.per_class[k]}, {"share", summary.percent(summary.per_class[k]) / 100.0}});
  nlohmann::json rows = nlohmann::json::array();
  for (const ClassifiedCell& c : cells) {
    const std::string_view label = class_label(c, queries, request.min_confidence);
    rows.push_back({{"position", {c.position_world.x(), c.position_world.y(), c.position_world.z()}},
                    {"class", label.empty() ? nlohmann::json() : nlohmann::json(std::string(label))},
                    {"score", c.match.score},
                    {"margin", c.match.margin},
                    {"count", c.count},
                    {"confidence", c.confidence}});
  }
  return {{"encoder", encoder_json(context)},
          {"served_from", context.map->source_kind()},
          {"queries", context.queries_name},
          {"region", map_answers_detail::region_json(request.region)},
          {"min_confidence", request.min_confidence},
          {"count", cells.size()},
          {"classes", std::move(classes)},
          {"uncertain", summary.uncertain},
          {"unclassified", summary.unclassified},
          {"statistics_unknown", summary.statistics_unknown},
          {"results", std::move(rows)},
          {"submaps_not_searched", std::move(not_searched)}};
}

nlohmann::json region_json(const std::optional<QueryRegion>& region) { return map_answers_detail::region_json(region); }

nlohmann::json answer_submaps(const AnswerContext& context) {
  return {{"encoder", encoder_json(context)}, {"served_from", context.map->source_kind()},
          {"submaps", context.map->info().at("submaps")}};
}

nlohmann::json answer_info(const AnswerContext& context) {
  nlohmann::json j = context.map->info();
  j["encoder"] = encoder_json(context);
  j["served_from"] = context.map->source_kind();
  return j;
}

}  // namespace slamvdb
