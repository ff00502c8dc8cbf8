// SemanticMapService builds its ANN index in the background (issue 21: `serve` answers at once):
// while the build runs every top-k question is scored exactly (the answer says so and equals
// similarity_search without an index); once it is ready the same question goes through the index
// and carries exact scores; a build that fails leaves the service exact, and a service destroyed
// during a build stops it instead of waiting for it to finish.
#include <gtest/gtest.h>

#include <future>
#include <map>
#include <random>

#include "slamvdb/server/map_service.hpp"

namespace slamvdb {
namespace {

constexpr int kServiceDim = 32;

// Three 50 x 50 patches, each cell near one of four prototypes plus noise: 7 500 cells.
std::shared_ptr<const SemanticMap> make_service_index_map() {
  MapParams params;
  params.semantic = {kServiceDim, EmbeddingPrecision::kFloat16};
  auto map = std::make_shared<SemanticMap>(params);
  std::mt19937 rng(3);
  std::normal_distribution<float> gauss(0.f, 1.f);
  std::vector<std::vector<float>> prototypes(4, std::vector<float>(kServiceDim));
  for (auto& p : prototypes)
    for (float& x : p) x = gauss(rng);
  std::vector<float> e(kServiceDim);
  for (int s = 0; s < 3; ++s) {
    VoxelMap voxels(params);
    for (int x = 0; x < 50; ++x)
      for (int y = 0; y < 50; ++y) {
        const auto& p = prototypes[static_cast<std::size_t>((x / 10 + y / 10 + s) % 4)];
        for (int d = 0; d < kServiceDim; ++d) e[static_cast<std::size_t>(d)] = p[static_cast<std::size_t>(d)] + 0.3f * gauss(rng);
        voxels.occupancy().set_log_odds({x, y, 0}, 1.0f);
        voxels.semantics().set({x, y, 0}, e.data(), 1);
      }
    SubmapInfo info;
    info.id = s;
    info.T_world_submap.translation() = Vec3d(s * 60 * params.occupancy.voxel_size, 0.0, 0.0);
    map->add_finished_submap(info, std::move(voxels));
  }
  return map;
}

std::vector<float> service_index_query() {
  std::vector<float> q(kServiceDim);
  for (int d = 0; d < kServiceDim; ++d) q[static_cast<std::size_t>(d)] = std::sin(0.7f * static_cast<float>(d));
  return q;
}

std::map<IndexCellKey, float> scores_by_cell(const std::vector<ScoredCell>& cells) {
  std::map<IndexCellKey, float> out;
  for (const ScoredCell& c : cells) out[c.cell] = c.score;
  return out;
}

TEST(SemanticMapServiceIndex, AnswersExactlyWhileTheIndexIsBuiltAndThroughItOnceReady) {
  const auto map = make_service_index_map();
  SemanticMapService service(map, nlohmann::json::object());
  EXPECT_EQ(service.index_state(), "none");
  std::promise<void> go;
  std::shared_future<void> gate = go.get_future().share();
  service.build_index_in_background([gate](const SemanticMap& m, const std::atomic<bool>&) {
    gate.wait();  // the build is held here until the test has asked its question
    return std::make_unique<AnnIndex>(m, AnnOptions{.lists = 16, .probes = 4});
  });
  EXPECT_EQ(service.index_state(), "building");
  EXPECT_THROW(service.build_index_in_background({}), Error);  // one build per service

  const std::vector<float> q = service_index_query();
  SearchOptions options;
  options.top_k = 25;
  const auto exact = similarity_search(*map, q, options);
  const auto during = service.search(q, options, false);
  EXPECT_FALSE(during.approximate);
  ASSERT_EQ(during.cells.size(), exact.size());
  for (std::size_t i = 0; i < exact.size(); ++i) {
    EXPECT_EQ(during.cells[i].cell, exact[i].cell);
    EXPECT_EQ(during.cells[i].score, exact[i].score);
  }
  EXPECT_FALSE(service.wait_for_index(std::chrono::milliseconds(20)));
  EXPECT_EQ(service.index_state(), "building");

  go.set_value();
  ASSERT_TRUE(service.wait_for_index(std::chrono::seconds(120)));
  EXPECT_EQ(service.index_state(), "ready");
  ASSERT_NE(service.ann(), nullptr);
  const auto after = service.search(q, options, false);
  EXPECT_TRUE(after.approximate);
  ASSERT_EQ(after.cells.size(), options.top_k);
  const auto every = scores_by_cell(similarity_search(*map, q, SearchOptions{}));
  for (const ScoredCell& c : after.cells) EXPECT_EQ(c.score, every.at(c.cell));  // exact scores
  EXPECT_FALSE(service.search(q, options, true).approximate);  // "exact": true still scans
}

TEST(SemanticMapServiceIndex, AFailedBuildLeavesItExactAndADestroyedServiceStopsItsBuild) {
  const auto map = make_service_index_map();
  const std::vector<float> q = service_index_query();
  SearchOptions options;
  options.top_k = 10;
  {
    SemanticMapService service(map, nlohmann::json::object());
    service.build_index_in_background(
        [](const SemanticMap&, const std::atomic<bool>&) -> std::unique_ptr<AnnIndex> { throw Error("no memory"); });
    ASSERT_TRUE(service.wait_for_index(std::chrono::seconds(30)));
    EXPECT_EQ(service.index_state(), "failed");
    EXPECT_FALSE(service.search(q, options, false).approximate);
  }
  // A build that only ends when asked to: the destructor asks (through AnnOptions::stop in serve).
  std::atomic<bool> saw_stop{false};
  const auto start = std::chrono::steady_clock::now();
  {
    SemanticMapService service(map, nlohmann::json::object());
    service.build_index_in_background([&saw_stop](const SemanticMap&, const std::atomic<bool>& stop) -> std::unique_ptr<AnnIndex> {
      while (!stop) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      saw_stop = true;
      throw Error("stopped");
    });
  }
  EXPECT_TRUE(saw_stop);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
  // AnnIndex itself honours the flag.
  std::atomic<bool> stop{true};
  EXPECT_THROW(AnnIndex(*map, AnnOptions{.stop = &stop}), Error);
}

}  // namespace
}  // namespace slamvdb
