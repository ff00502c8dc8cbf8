// The server's request decoding on its own (no socket): every field as documented, every refusal
// naming its field, and limits that hold whatever the request says.
#include "slamvdb/server/request_decoding.hpp"

#include <gtest/gtest.h>

#include <memory>

#include "slamvdb/server/text_embedding_cache.hpp"

namespace slamvdb {
namespace {

// The field a body is refused for ("" for the body as a whole), or "accepted".
std::string refused_field(const std::string& body, const ServerLimits& limits = {}) {
  try {
    decode_query_request(body, 3, limits);
    return "accepted";
  } catch (const RequestError& e) {
    EXPECT_EQ(e.status(), 400) << body;
    EXPECT_FALSE(std::string(e.what()).empty());
    return e.field();
  }
}

TEST(RequestDecoding, QueryFieldsAsDocumented) {
  const QueryRequest r = decode_query_request(
      R"({"text": ["tall grass", "dirt"], "not": "puddle", "class": "smooth", "not_class": ["rough"],
          "vector": [[1, 0, 0], [0, 1, 0.5]], "not_vector": [0, 0, 1], "top_k": 7, "threshold": 0.25, "exact": true})",
      3, {});
  EXPECT_EQ(r.terms.text, (std::vector<std::string>{"tall grass", "dirt"}));
  EXPECT_EQ(r.terms.not_text, (std::vector<std::string>{"puddle"}));
  EXPECT_EQ(r.terms.classes, (std::vector<std::string>{"smooth"}));
  EXPECT_EQ(r.terms.not_classes, (std::vector<std::string>{"rough"}));
  ASSERT_EQ(r.terms.vectors.size(), 2u);
  EXPECT_FLOAT_EQ(r.terms.vectors[1][2], 0.5f);
  ASSERT_EQ(r.terms.not_vectors.size(), 1u);
  EXPECT_FLOAT_EQ(r.terms.not_vectors[0][2], 1.f);
  EXPECT_EQ(r.search.top_k, 7u);
  EXPECT_FLOAT_EQ(r.search.threshold, 0.25f);
  EXPECT_TRUE(r.exact);
  // Defaults: the CLI's (top 100, no threshold).
  const QueryRequest d = decode_query_request(R"({"text": "grass"})", 3, {});
  EXPECT_EQ(d.search.top_k, 100u);
  EXPECT_FALSE(std::isfinite(d.search.threshold));
  EXPECT_FALSE(d.top_k_capped);
  // top_k 0 with a threshold: every cell above it, at most max_top_k.
  ServerLimits limits;
  limits.max_top_k = 50;
  const QueryRequest all = decode_query_request(R"({"text": "grass", "top_k": 0, "threshold": 0.1})", 3, limits);
  EXPECT_EQ(all.search.top_k, 50u);
  EXPECT_TRUE(all.top_k_capped);
}

TEST(RequestDecoding, RegionsAsDocumentedAndRefusalsNamingTheirPart) {
  const QueryRequest box = decode_query_request(R"({"text": "grass", "region": {"bbox": [0, -1, -2, 3, 4, 5]}})", 3, {});
  ASSERT_TRUE(box.search.region && box.search.region->box);
  EXPECT_EQ(box.search.region->box->min(), Vec3d(0, -1, -2));
  EXPECT_EQ(box.search.region->box->max(), Vec3d(3, 4, 5));
  EXPECT_FALSE(box.search.region->near);
  const QueryRequest near = decode_query_request(R"({"text": "grass", "region": {"near": [1, 2], "radius": 3.5}})", 3, {});
  ASSERT_TRUE(near.search.region && near.search.region->near);
  EXPECT_TRUE(near.search.region->near->horizontal);
  EXPECT_EQ(near.search.region->near->radius, 3.5);
  EXPECT_FALSE(decode_query_request(R"({"text": "grass"})", 3, {}).search.region);
  EXPECT_EQ(refused_field(R"({"text": "g", "region": [0, 0, 0, 1, 1, 1]})"), "region");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {}})"), "region.bbox");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"box": [0, 0, 0, 1, 1, 1]}})"), "region.box");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"bbox": [0, 0, 0, 1, 1]}})"), "region.bbox");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"bbox": [0, 0, 0, 1, 1, "1"]}})"), "region.bbox");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"bbox": [0, 0, 2, 1, 1, 1]}})"), "region.bbox");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"bbox": [0, 0, 0, 1, 1, 1e999]}})"), "");  // not JSON's numbers
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"near": [1, 2, 3, 4], "radius": 1}})"), "region.near");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"near": [1, 2]}})"), "region.radius");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"near": [1, 2], "radius": 0}})"), "region.radius");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"near": [1, 2], "radius": "5"}})"), "region.radius");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"radius": 5}})"), "region.near");
  EXPECT_EQ(refused_field(R"({"text": "g", "region": {"near": 5, "radius": 5}})"), "region.near");
}

TEST(RequestDecoding, RefusalsNameTheField) {
  EXPECT_EQ(refused_field(""), "");
  EXPECT_EQ(refused_field("{"), "");
  EXPECT_EQ(refused_field("\"text\""), "");
  EXPECT_EQ(refused_field("{\"text\": \"\xff\"}"), "");  // not UTF-8
  EXPECT_EQ(refused_field(std::string(100000, '[') + std::string(100000, ']')), "");  // depth, no deep tree built
  EXPECT_EQ(refused_field(R"({"text": "grass", "topk": 3})"), "topk");
  EXPECT_EQ(refused_field(R"({"text": ""})"), "text");
  EXPECT_EQ(refused_field(R"({"text": ["grass", 3]})"), "text");
  EXPECT_EQ(refused_field(R"({"not": "grass"})"), "text");  // no positive term
  EXPECT_EQ(refused_field(R"({"class": {"a": 1}})"), "class");
  EXPECT_EQ(refused_field(R"({"vector": [1, 0]})"), "vector");
  EXPECT_EQ(refused_field(R"({"vector": [1, 0, "x"]})"), "vector");
  EXPECT_EQ(refused_field(R"({"vector": [1, 0, 1e39]})"), "vector");  // not a finite float
  EXPECT_EQ(refused_field(R"({"vector": [1, 0, 0], "not_vector": [[1, 0]]})"), "not_vector");
  EXPECT_EQ(refused_field(R"({"text": "grass", "top_k": 2.5})"), "top_k");
  EXPECT_EQ(refused_field(R"({"text": "grass", "top_k": -1})"), "top_k");
  EXPECT_EQ(refused_field(R"({"text": "grass", "top_k": 10001})"), "top_k");
  EXPECT_EQ(refused_field(R"({"text": "grass", "top_k": 0})"), "top_k");
  EXPECT_EQ(refused_field(R"({"text": "grass", "threshold": "high"})"), "threshold");
  EXPECT_EQ(refused_field(R"({"text": "grass", "threshold": -1.5})"), "threshold");
  EXPECT_EQ(refused_field(R"({"text": "grass", "exact": 1})"), "exact");
  ServerLimits limits;
  limits.max_terms = 2;
  limits.max_text_bytes = 5;
  EXPECT_EQ(refused_field(R"({"text": ["a", "b", "c"]})", limits), "");
  EXPECT_EQ(refused_field(R"({"text": "grasses"})", limits), "text");
  EXPECT_EQ(refused_field(R"({"text": ["a", "b"]})", limits), "accepted");
}

TEST(RequestDecoding, AtFieldsAndLimits) {
  const AtRequest r = decode_at_request(R"({"points": [[1, 2, 3], [-4.5, 0, 1e3]], "embedding": true})", {});
  ASSERT_EQ(r.points.size(), 2u);
  EXPECT_EQ(r.points[1], Vec3d(-4.5, 0, 1000));
  EXPECT_TRUE(r.embedding);
  EXPECT_FALSE(decode_at_request(R"({"points": [[0, 0, 0]]})", {}).embedding);
  ServerLimits limits;
  limits.max_points = 2;
  const auto field_of = [&](const std::string& body) -> std::string {
    try {
      decode_at_request(body, limits);
      return "accepted";
    } catch (const RequestError& e) {
      return e.field();
    }
  };
  EXPECT_EQ(field_of(R"({"points": [[0, 0, 0], [1, 1, 1]]})"), "accepted");
  EXPECT_EQ(field_of(R"({"points": [[0, 0, 0], [1, 1, 1], [2, 2, 2]]})"), "points");
  EXPECT_EQ(field_of(R"({"points": []})"), "points");
  EXPECT_EQ(field_of(R"({"points": [[0, 0]]})"), "points");
  EXPECT_EQ(field_of(R"({"points": [[0, 0, "1"]]})"), "points");
  EXPECT_NE(field_of(R"({"points": [[0, 0, 1e400]]})"), "accepted");  // not a finite double
  EXPECT_EQ(field_of(R"({})"), "points");
  EXPECT_EQ(field_of(R"({"points": [[0, 0, 0]], "embedding": 1})"), "embedding");
  EXPECT_EQ(field_of(R"({"points": [[0, 0, 0]], "xyz": 1})"), "xyz");
}

TEST(RequestDecoding, ErrorBody) {
  EXPECT_EQ(error_json("bad", "top_k").dump(), R"({"error":{"field":"top_k","message":"bad"}})");
  EXPECT_TRUE(error_json("bad", "")["error"]["field"].is_null());
}

// A text encoder that counts its calls.
class CountingTextEncoder : public TextEncoder {
 public:
  explicit CountingTextEncoder(int* calls) : calls_(calls) {}
  std::vector<float> encode(std::string_view text) override {
    ++*calls_;
    return {static_cast<float>(text.size()), 1.f};
  }
  int dim() const override { return 2; }
  std::string model_id() const override { return "counting"; }

 private:
  int* calls_;
};

TEST(TextEmbeddingCache, EncodesEachTextOnceAndForgetsTheLeastRecent) {
  int calls = 0;
  TextEmbeddingCache cache(std::make_unique<CountingTextEncoder>(&calls), true, 2);
  EXPECT_EQ(cache.info().model_id, "counting");
  EXPECT_TRUE(cache.info().simulated);
  EXPECT_FLOAT_EQ(cache.embed("abc")[0], 3.f);
  EXPECT_FLOAT_EQ(cache.embed("abc")[0], 3.f);
  EXPECT_EQ(calls, 1);
  cache.embed("de");
  cache.embed("abc");  // most recent now: "abc", then "de"
  cache.embed("f");    // evicts "de"
  EXPECT_EQ(calls, 3);
  cache.embed("abc");
  EXPECT_EQ(calls, 3);
  cache.embed("de");
  EXPECT_EQ(calls, 4);
  const auto counts = cache.counts();
  EXPECT_EQ(counts.size, 2u);
  EXPECT_EQ(counts.hits, 3u);
  EXPECT_EQ(counts.misses, 4u);
}

}  // namespace
}  // namespace slamvdb
