// The paper's map evaluation on a hand-made map whose answers are worked out below.
#include "slamvdb/eval/map_evaluation.hpp"

#include <gtest/gtest.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

Ontology tiny_ontology() {
  return Ontology::parse(R"(
name: tiny
void: [void]
void_pixels: train
unlabelled_ids: [99]
classes:
  - {name: rough, rgb: [0, 200, 0], cost: 2}
  - {name: obstacle, rgb: [200, 0, 0], cost: .inf}
  - {name: void, rgb: [0, 0, 0]}
labels:
  - {id: 0, name: sky, rgb: [0, 0, 255], class: void}
  - {id: 1, name: grass, rgb: [0, 255, 0], class: rough}
  - {id: 2, name: tree, rgb: [255, 0, 0], class: obstacle}
)",
                         "tiny ontology");
}

QuerySet tiny_queries(const Ontology& o) {
  QueryMatrix q = QueryMatrix::Identity(3, 3);  // rough = e0, obstacle = e1, void = e2
  return make_query_set(o, q, "test-space");
}

// 1 m voxels along x: cell 0 looks rough, cell 1 obstacle, cell 2 looks void (second best:
// obstacle), cell 3 rough but no LiDAR point falls into it.
SemanticMap tiny_map() {
  MapParams p;
  p.occupancy.voxel_size = 1.0;
  p.semantic = {3, EmbeddingPrecision::kFloat32};
  p.submap_length = 0;
  SemanticMap map(p, {"test-space", "tiny", "hand-made test map"});
  VoxelMap v(p);
  const float e[4][3] = {{1, 0.1f, 0}, {0.1f, 1, 0}, {0, 0.2f, 1}, {1, 0, 0}};
  for (int x = 0; x < 4; ++x) {
    v.occupancy().set_log_odds({x, 0, 0}, 2.0f);
    v.semantics().set({x, 0, 0}, e[x], 5);
  }
  map.add_finished_submap({}, std::move(v));
  return map;
}

GroundTruthScan scan_of(std::vector<std::pair<float, uint16_t>> x_and_label) {
  return {Pose::Identity(),
          [pts = std::move(x_and_label)] {
            LidarScan s;
            for (const auto& [x, label] : pts) {
              s.points.emplace_back(x, 0.5f, 0.5f);
              s.labels.push_back(label);
            }
            return s;
          },
          "hand-made scan"};
}

TEST(MapEvaluation, HitRateAndVoxelLabellingAsWorkedOut) {
  const Ontology o = tiny_ontology();
  const SemanticMap map = tiny_map();
  // cell 0: 3 grass, 1 tree, 1 sky (void: ignored), 1 unlabelled -> truth rough, predicted rough
  // cell 1: 2 grass, 2 tree (a tie: the first class, rough)        -> truth rough, predicted obstacle
  // cell 2: 1 tree                                                  -> truth obstacle, predicted obstacle (void rule)
  // two points outside every voxel, one point of no return
  const std::vector<GroundTruthScan> scans = {
      scan_of({{0.5f, 1}, {0.2f, 1}, {0.7f, 1}, {0.5f, 2}, {0.5f, 0}, {0.5f, 99}, {1.5f, 1}}),
      scan_of({{1.2f, 1}, {1.4f, 2}, {1.6f, 2}, {2.5f, 2}, {10.5f, 1}, {-3.5f, 2}})};
  const MapEvaluation r = evaluate_map(map, scans, tiny_queries(o), o);
  EXPECT_EQ(r.points_total, 13u);
  EXPECT_EQ(r.points_void, 1u);
  EXPECT_EQ(r.points_unlabelled, 1u);
  EXPECT_EQ(r.points_outside, 2u);
  // Hit rate: 9 counted points; hits: 3 grass in cell 0, 2 trees in cell 1, 1 tree in cell 2.
  ASSERT_TRUE(r.report.hit_rate);
  EXPECT_DOUBLE_EQ(*r.report.hit_rate, 6.0 / 9.0);
  ASSERT_EQ(r.report.classes.size(), 2u);  // void is not reported
  const ClassMetrics &rough = r.report.classes[0], &obstacle = r.report.classes[1];
  EXPECT_EQ(rough.name, "rough");
  EXPECT_DOUBLE_EQ(*rough.hit, 3.0 / 5.0);    // 3 of the 5 grass points are in rough voxels
  EXPECT_DOUBLE_EQ(*obstacle.hit, 3.0 / 4.0);  // 3 of the 4 tree points are in obstacle voxels
  // Voxel-wise: (rough, rough), (rough, obstacle), (obstacle, obstacle); cell 3 has no point.
  EXPECT_EQ(r.cells_with_points, 3u);
  EXPECT_EQ(r.map_cells, 4u);
  EXPECT_DOUBLE_EQ(*r.report.accuracy, 2.0 / 3.0);
  EXPECT_EQ(rough.relevant, 2u);
  EXPECT_EQ(rough.recalled, 1u);
  EXPECT_DOUBLE_EQ(*rough.recall, 0.5);
  EXPECT_DOUBLE_EQ(*rough.precision, 1.0);
  EXPECT_DOUBLE_EQ(*rough.iou, 0.5);
  EXPECT_EQ(obstacle.relevant, 1u);
  EXPECT_EQ(obstacle.recalled, 2u);
  EXPECT_DOUBLE_EQ(*obstacle.recall, 1.0);
  EXPECT_DOUBLE_EQ(*obstacle.precision, 0.5);
  EXPECT_DOUBLE_EQ(*obstacle.iou, 0.5);
  EXPECT_DOUBLE_EQ(*r.report.miou, 0.5);
  const std::string table = to_markdown(r.report);
  EXPECT_NE(table.find("| *all* | 66.67 | 66.67 |"), std::string::npos) << table;
}

TEST(MapEvaluation, WithoutTheVoidRuleAVoidVoxelIsAMiss) {
  const Ontology o = tiny_ontology();
  MapEvaluationOptions options;
  options.classify.void_to_second_best = false;
  const MapEvaluation r = evaluate_map(tiny_map(), {scan_of({{2.5f, 2}})}, tiny_queries(o), o, options);
  EXPECT_DOUBLE_EQ(*r.report.hit_rate, 0.0);  // the voxel says void, the point says tree
  EXPECT_DOUBLE_EQ(*r.report.accuracy, 0.0);
}

TEST(MapEvaluation, RefusesQueriesOfAnotherSpaceAndUnknownLabels) {
  const Ontology o = tiny_ontology();
  QuerySet other = tiny_queries(o);
  other.model_id = "another-space";
  EXPECT_THROW(evaluate_map(tiny_map(), {scan_of({{0.5f, 1}})}, other, o), Error);
  QuerySet wrong_dim = tiny_queries(o);
  wrong_dim.vectors = QueryMatrix::Identity(3, 4);
  EXPECT_THROW(evaluate_map(tiny_map(), {scan_of({{0.5f, 1}})}, wrong_dim, o), Error);
  try {
    evaluate_map(tiny_map(), {scan_of({{0.5f, 7}})}, tiny_queries(o), o);
    FAIL() << "an unknown label id must be an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("label id 7"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace slamvdb
