// Live mode answers from memory only (live_map_service.hpp): a submap that left memory (`map
// --max-memory`, --unload-radius) is not searched, and every answer of a question says so, so that
// nobody takes a partial answer for the whole map. A real MapServer on loopback over a
// LiveMapService: POST /api/query, POST /api/at and GET /api/classes find a submap's voxels while it
// is in memory ("submaps_not_searched": []), not while it is out ([its id]), and again once it is
// read back.
#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "slamvdb/server/http_server.hpp"
#include "slamvdb/server/httplib_include.hpp"
#include "slamvdb/server/live_map_service.hpp"

namespace slamvdb {
namespace {

constexpr int kPatchDim = 8;

// Three finished submaps 10 m apart, ids 0 to 2: submap k a 4 x 4 patch of cells whose embeddings
// point along axis k.
void build_three_submaps(SemanticMap& map) {
  for (int id = 0; id < 3; ++id) {
    VoxelMap voxels(map.params());
    std::vector<float> e(kPatchDim, 0.f);
    e[static_cast<std::size_t>(id)] = 1.f;
    for (int x = 0; x < 4; ++x)
      for (int y = 0; y < 4; ++y) {
        voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
        voxels.semantics().set({x, y, 0}, e.data(), 3);
      }
    SubmapInfo info;
    info.id = id;
    info.T_world_submap.translation() = Vec3d(10.0 * id, 0, 0);
    info.finished = true;
    map.add_finished_submap(info, std::move(voxels));
  }
}

QuerySet three_axes() {
  QuerySet q;
  q.model_id = "test-space";  // not checked (ModelIdCheck::kIgnore); a query set must name one
  q.names = {"zero", "one", "two"};
  q.vectors = QueryMatrix::Zero(3, kPatchDim);
  for (int k = 0; k < 3; ++k) q.vectors(k, k) = 1;
  return q;
}

TEST(LiveMapAnswers, QuestionsSayWhichSubmapsOutOfMemoryWereNotSearched) {
  MapParams params;
  params.semantic = {kPatchDim, EmbeddingPrecision::kFloat32};
  params.submap_length = 0;
  SemanticMap map(params);
  build_three_submaps(map);
  const double voxel = params.occupancy.voxel_size;
  const Vec3d in_submap_2(20.0 + 1.5 * voxel, 1.5 * voxel, 0.5 * voxel);
  std::map<int, SubmapInfo> kept;  // what the holder keeps of the submaps out of memory (Mapper::submaps)
  auto live = std::make_shared<LiveMapService>("SIMULATED patches", kPatchDim, LiveMapOptions{.refresh_seconds = 3600.0});
  live->attach(map, [&] {
    std::vector<SubmapInfo> all = map.submaps();
    for (const auto& [id, info] : kept) all.push_back(info);
    return all;
  });
  ServerOptions options;
  options.port = 0;
  options.limits.rate_per_client = 0;
  options.model_check = ModelIdCheck::kIgnore;
  MapServer server(live, nullptr, three_axes(), options);
  const int port = server.bind();
  std::thread running([&] { server.run(); });
  struct Stop {  // also when an assertion returns early
    MapServer& server;
    std::thread& running;
    ~Stop() {
      server.stop();
      running.join();
    }
  } stop{server, running};
  httplib::Client client("127.0.0.1", port);

  nlohmann::json axis_2 = nlohmann::json::array();
  for (int i = 0; i < kPatchDim; ++i) axis_2.push_back(i == 2 ? 1.0 : 0.0);
  const std::string query = nlohmann::json{{"vector", axis_2}, {"top_k", 5}, {"exact", true}}.dump();
  const std::string at = nlohmann::json{{"points", {{in_submap_2.x(), in_submap_2.y(), in_submap_2.z()}}}}.dump();
  struct Answers {
    nlohmann::json query, at, classes;
  };
  const auto parse = [](const httplib::Result& r) {
    EXPECT_TRUE(r && r->status == 200) << (r ? r->body : "no answer");
    return r && r->status == 200 ? nlohmann::json::parse(r->body) : nlohmann::json::object();
  };
  const auto ask = [&] {
    return Answers{parse(client.Post("/api/query", query, "application/json")),
                   parse(client.Post("/api/at", at, "application/json")),
                   parse(client.Get("/api/classes?bbox=-5,-5,-5,40,5,5"))};
  };
  const auto classified_two = [](const nlohmann::json& classes) {
    for (const auto& c : classes.at("classes"))
      if (c.at("name") == "two") return c.at("voxels").get<int>();
    return -1;
  };
  const nlohmann::json none = nlohmann::json::array();

  // All in memory: submap 2's cells answer, nothing left out.
  const Answers whole = ask();
  ASSERT_FALSE(whole.query.at("results").empty());
  EXPECT_NEAR(whole.query.at("results")[0].at("score").get<double>(), 1.0, 1e-6);
  EXPECT_TRUE(whole.at.at("results")[0].at("found").get<bool>()) << whole.at.dump();
  EXPECT_EQ(classified_two(whole.classes), 16) << whole.classes.dump();
  for (const auto* a : {&whole.query, &whole.at, &whole.classes}) EXPECT_EQ(a->at("submaps_not_searched"), none);

  // Submap 2 leaves memory: not searched, and every answer says so.
  auto [info2, voxels2] = map.remove_finished_submap(2);
  kept[2] = info2;
  const Answers partial = ask();
  if (!partial.query.at("results").empty()) {
    EXPECT_LT(partial.query.at("results")[0].at("score").get<double>(), 0.5) << partial.query.dump();
  }
  EXPECT_FALSE(partial.at.at("results")[0].at("found").get<bool>()) << partial.at.dump();
  EXPECT_EQ(classified_two(partial.classes), 0) << partial.classes.dump();
  for (const auto* a : {&partial.query, &partial.at, &partial.classes})
    EXPECT_EQ(a->at("submaps_not_searched"), nlohmann::json::array({2})) << a->dump();

  // Read back: whole again.
  kept.erase(2);
  map.add_finished_submap(info2, std::move(voxels2));
  const Answers back = ask();
  EXPECT_TRUE(back.at.at("results")[0].at("found").get<bool>());
  for (const auto* a : {&back.query, &back.at, &back.classes}) EXPECT_EQ(a->at("submaps_not_searched"), none);

  live->detach();
}

}  // namespace
}  // namespace slamvdb
