// The per-request time budget (serve --time-budget, issue 21 "Security and limits"): the map-wide
// loops (similarity search, the ANN index's lists, classification, point look-ups) check a
// Deadline between chunks and stop with DeadlineExceeded once it has passed; a real MapServer on
// loopback answers such a request 503 with a message naming --time-budget, counts it in /metrics,
// and keeps answering; the same request without a budget is answered.
#include <gtest/gtest.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "slamvdb/core/deadline.hpp"
#include "slamvdb/query/ann_index.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/server/http_server.hpp"
#include "slamvdb/server/httplib_include.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb {
namespace {

// One submap of side x side 512-d fp16 cells (two directions, a little noise): enough cells that
// scoring them all takes far longer than the budgets below, also on an idle fast core.
std::shared_ptr<SemanticMap> budget_map(int side) {
  MapParams params;
  params.semantic = {512, EmbeddingPrecision::kFloat16};
  params.submap_length = 0;
  auto map = std::make_shared<SemanticMap>(params);
  VoxelMap voxels(params);
  std::vector<float> e(512);
  for (int x = 0; x < side; ++x)
    for (int y = 0; y < side; ++y) {
      std::fill(e.begin(), e.end(), 0.01f * static_cast<float>((x * 7 + y * 13) % 17));
      e[(x + y) % 2] += 1.f;
      voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
      voxels.semantics().set({x, y, 0}, e.data(), 1 + (x + y) % 5);
    }
  map->add_finished_submap(SubmapInfo{}, std::move(voxels));
  return map;
}

QuerySet two_directions() {
  QuerySet q;
  q.model_id = "test-space";
  q.names = {"first", "second"};
  q.vectors = QueryMatrix::Zero(2, 512);
  q.vectors(0, 0) = q.vectors(1, 1) = 1;
  return q;
}

TEST(TimeBudget, MapWideLoopsStopOnceTheDeadlineHasPassed) {
  const auto map = budget_map(testing::test_size(64, 32));
  std::vector<float> q(512, 0.f);
  q[0] = 1.f;
  const Deadline passed(Deadline::Clock::now() - std::chrono::seconds(1));
  SearchOptions search;
  search.deadline = passed;
  EXPECT_THROW(similarity_search(*map, q, search), DeadlineExceeded);
  search.region = QueryRegion{};
  search.region->box = Eigen::AlignedBox3d(Vec3d(-100, -100, -100), Vec3d(100, 100, 100));
  EXPECT_THROW(similarity_search(*map, q, search), DeadlineExceeded);  // the region's cells too
  ClassifyOptions classify;
  classify.deadline = passed;
  const QuerySet queries = two_directions();
  EXPECT_THROW(classify_map(*map, queries, classify, ModelIdCheck::kIgnore), DeadlineExceeded);
  const std::vector<Vec3d> points(10, Vec3d(1, 1, 0));
  EXPECT_THROW(query_points(*map, points, nullptr, classify), DeadlineExceeded);
  AnnOptions ann;
  ann.lists = 8;
  const AnnIndex index(*map, ann);
  EXPECT_THROW(index.candidates(q, 0, 10, nullptr, passed), DeadlineExceeded);
  // No deadline (or a zero budget, which means none): the answers.
  EXPECT_FALSE(Deadline::after(std::chrono::microseconds(0)).set());
  search = {};
  search.top_k = 5;
  search.deadline = Deadline::after(std::chrono::microseconds(0));
  EXPECT_EQ(similarity_search(*map, q, search).size(), 5u);
  EXPECT_EQ(classify_map(*map, queries, {}, ModelIdCheck::kIgnore).size(), map->num_index_cells());
  EXPECT_FALSE(index.candidates(q, 0, 10).empty());
}

TEST(ServeTimeBudget, ATinyBudgetAnswers503NamingTheOptionCountsItAndTheServerGoesOn) {
  // Exact scoring of 50 k 512-d cells takes milliseconds; the budget is 50 microseconds.
  const auto map = budget_map(testing::test_size(224, 100));
  auto service = std::make_shared<SemanticMapService>(map, nlohmann::json{{"submaps", nlohmann::json::array()}});
  const auto serve = [&](std::chrono::microseconds budget) {
    ServerOptions options;
    options.port = 0;
    options.limits.time_budget = budget;
    options.limits.rate_per_client = 0;
    options.model_check = ModelIdCheck::kIgnore;
    return std::make_unique<MapServer>(service, nullptr, two_directions(), options);
  };
  nlohmann::json vector = nlohmann::json::array();
  for (int i = 0; i < 512; ++i) vector.push_back(i == 0 ? 1.0 : 0.0);
  const std::string every_cell = nlohmann::json{{"vector", vector}, {"top_k", 0}, {"threshold", -1}, {"exact", true}}.dump();
  const std::string at = nlohmann::json{{"points", nlohmann::json::array({{1, 1, 0}, {2, 2, 0}})}}.dump();

  const auto server = serve(std::chrono::microseconds(50));
  const int port = server->bind();
  std::thread running([&] { server->run(); });
  httplib::Client client("127.0.0.1", port);
  const auto refused = client.Post("/api/query", every_cell, "application/json");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 503) << refused->body;
  const auto error = nlohmann::json::parse(refused->body).at("error");
  EXPECT_NE(error.at("message").get<std::string>().find("--time-budget"), std::string::npos) << error;
  EXPECT_TRUE(error.at("field").is_null());
  const auto classes = client.Get("/api/classes?bbox=-1000,-1000,-10,1000,1000,10");  // every cell classified
  ASSERT_TRUE(classes);
  EXPECT_EQ(classes->status, 503) << classes->body;
  // The server goes on: small answers fit in the budget... or are refused the same way, never dropped.
  const auto small = client.Post("/api/at", at, "application/json");
  ASSERT_TRUE(small);
  EXPECT_TRUE(small->status == 200 || small->status == 503) << small->body;
  const auto metrics = client.Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("slamvdb_http_time_budget_exceeded_total{route=\"/api/query\"} 1\n"), std::string::npos)
      << metrics->body;
  EXPECT_NE(metrics->body.find("slamvdb_http_time_budget_exceeded_total{route=\"/api/classes\"} 1\n"), std::string::npos);
  EXPECT_NE(metrics->body.find("slamvdb_http_requests_total{route=\"/api/query\",status=\"503\"} 1\n"), std::string::npos);
  server->stop();
  running.join();

  // Without a budget the same question is answered in full.
  const auto unlimited = serve(std::chrono::microseconds(0));
  const int port2 = unlimited->bind();
  std::thread running2([&] { unlimited->run(); });
  httplib::Client client2("127.0.0.1", port2);
  const auto answered = client2.Post("/api/query", every_cell, "application/json");
  ASSERT_TRUE(answered);
  EXPECT_EQ(answered->status, 200);
  EXPECT_EQ(nlohmann::json::parse(answered->body).at("count").get<std::size_t>(),
            std::min<std::size_t>(ServerLimits{}.max_top_k, map->num_index_cells()));
  unlimited->stop();
  running2.join();
}

}  // namespace
}  // namespace slamvdb
