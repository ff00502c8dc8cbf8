// `slamvdb serve` with its ANN index (--ann-min-cells 0 builds it even for the small test map): a
// top-k question goes through the index and says "exact": false, every row it answers carries the
// cell's exact score; "exact": true, a threshold, a region and a `not` term are scored exactly and
// equal the CLI's rows; without the option a small map gets no index at all.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <thread>
#include <nlohmann/json.hpp>

#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

using testing::ServerProcess;
using testing::TwoClassMap;

nlohmann::json serve_ann_post(httplib::Client& client, const nlohmann::json& body) {
  const auto res = client.Post("/api/query", body.dump(), "application/json");
  EXPECT_TRUE(res);
  if (!res) return {};
  EXPECT_EQ(res->status, 200) << body.dump() << "\n" << res->body;
  return nlohmann::json::parse(res->body);
}

TEST(ServeAnn, TopKGoesThroughTheIndexWithExactScoresAndExactTrueEqualsTheCli) {
  TwoClassMap f;
  ServerProcess server(SLAMVDB_CLI_PATH,
                       {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(), "--ignore-model-id",
                        "--ann-min-cells", "0"},
                       (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  // The index is built in the background (GET /healthz says "building" meanwhile; a question is
  // then scored exactly, see map_service_index_test.cpp): wait until it is ready.
  std::string state;
  for (int i = 0; i < 600 && state != "ready"; ++i) {
    const auto health = client.Get("/healthz");
    ASSERT_TRUE(health && health->status == 200);
    state = nlohmann::json::parse(health->body).at("index").get<std::string>();
    ASSERT_TRUE(state == "building" || state == "ready") << state;
    if (state != "ready") std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_EQ(state, "ready") << server.output();
  EXPECT_NE(server.output().find("ANN index: building"), std::string::npos) << server.output();  // spdlog: stdout

  // Every cell's exact score (a threshold question never uses the index).
  const nlohmann::json every = serve_ann_post(client, {{"text", "grass"}, {"top_k", 0}, {"threshold", -1}});
  EXPECT_TRUE(every.at("exact").get<bool>());
  ASSERT_EQ(every.at("count").get<std::size_t>(), f.semantic_cells);
  std::map<std::vector<double>, float> exact_score;
  for (const auto& r : every.at("results")) exact_score[r.at("position").get<std::vector<double>>()] = r.at("score");

  const nlohmann::json approximate = serve_ann_post(client, {{"text", "grass"}, {"top_k", 7}});
  EXPECT_FALSE(approximate.at("exact").get<bool>());
  ASSERT_EQ(approximate.at("count").get<std::size_t>(), 7u);
  float previous = 2.f;
  for (const auto& r : approximate.at("results")) {
    const auto at = exact_score.find(r.at("position").get<std::vector<double>>());
    ASSERT_NE(at, exact_score.end());
    EXPECT_EQ(r.at("score").get<float>(), at->second);  // re-ranked exactly
    EXPECT_LE(r.at("score").get<float>(), previous);
    previous = r.at("score").get<float>();
  }

  // Asked exact, with a `not` term, or in a region: every cell scored, the CLI's rows.
  const std::vector<std::pair<nlohmann::json, std::string>> exact_cases = {
      {{{"text", "grass"}, {"top_k", 7}, {"exact", true}}, "--text grass --top-k 7"},
      {{{"text", "grass"}, {"not", "tree"}, {"top_k", 5}}, "--text grass --not tree --top-k 5"},
      {{{"class", "rough"}, {"top_k", 6}, {"region", {{"bbox", {-5, -5, -5, 5, 5, 5}}}}},
       "--class rough --top-k 6 --bbox=-5,-5,-5,5,5,5"},
  };
  for (const auto& [body, args] : exact_cases) {
    const nlohmann::json answer = serve_ann_post(client, body);
    EXPECT_TRUE(answer.at("exact").get<bool>()) << body.dump();
    const auto out = f.tmp.path / "cli.csv";
    const auto r = testing::run_command(f.cli("query " + testing::shell_quote(f.map.string()) + " " + args +
                                              " --queries " + testing::shell_quote(f.queries.string()) +
                                              " --ignore-model-id -o " + testing::shell_quote(out.string())));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    std::string error;
    const auto records = testing::read_csv_strict(testing::read_text_file(out), &error);
    ASSERT_TRUE(records && records->size() > 1) << error;
    EXPECT_EQ(testing::query_answer_rows(answer), std::vector<std::vector<std::string>>(records->begin() + 1, records->end()))
        << body.dump();
  }
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

TEST(ServeAnn, ASmallMapGetsNoIndexByDefault) {
  TwoClassMap f;
  ServerProcess server(SLAMVDB_CLI_PATH, {"serve", f.map.string(), "--port", "0", "--ignore-model-id"},
                       (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  EXPECT_TRUE(serve_ann_post(client, {{"text", "grass"}, {"top_k", 7}}).at("exact").get<bool>());
  EXPECT_EQ(server.output().find("ANN index: "), std::string::npos) << server.output();
  const auto health = client.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(nlohmann::json::parse(health->body).at("index"), "none");
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

}  // namespace
}  // namespace slamvdb
