// Asking a map built from a SIMULATED sequence: the paper's evaluation end to end, fusion against
// the per-image baseline, composite text queries and point look-ups.
#include <gtest/gtest.h>

#include <iostream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/eval/image_baseline.hpp"
#include "slamvdb/eval/map_evaluation.hpp"
#include "slamvdb/query/class_confidence.hpp"
#include "slamvdb/testing/pipeline_fixture.hpp"

namespace slamvdb {
namespace {
using testing::MappingPipelineTest;

// Text queries for the coarse classes from the simulated text encoder of the same space.
QuerySet text_queries(const SimulatedEncoderConfig& config, const Ontology& ontology) {
  SimulatedTextEncoder text(config);
  QueryMatrix q(ontology.num_classes(), config.dim);
  for (int k = 0; k < ontology.num_classes(); ++k)
    q.row(k) = Eigen::Map<const Eigen::RowVectorXf>(text.encode(ontology.classes()[k].name).data(), config.dim);
  return make_query_set(ontology, q, text.model_id());
}

std::vector<GroundTruthScan> ground_truth_scans(const Sequence& seq) {
  std::vector<GroundTruthScan> scans;
  for (const ScanRecord& rec : seq.scans)
    scans.push_back({*seq.poses.at(rec.stamp), [rec] { return read_scan(rec); }, rec.points.filename().string()});
  return scans;
}

TEST_F(MappingPipelineTest, EvaluationEndToEndAndFusionAgainstThePerImageBaseline) {
  const Sequence seq = read_sequence(dir_);
  const Ontology ontology = Ontology::builtin("rellis3d-coarse");
  struct Result {
    double map_accuracy, hit_rate, baseline_accuracy;
  };
  auto run = [&](float confusion, float related) {
    SimulatedEncoderConfig config = encoder_config();
    config.confusion_rate = confusion;
    config.related_confusion = related;
    EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(config), EncoderFeatureSource::Input::kLabels);
    PipelineReport report;
    const SemanticMap map = build_map(seq, &source, options(), report);
    const QuerySet queries = text_queries(config, ontology);
    const MapEvaluation e = evaluate_map(map, ground_truth_scans(seq), queries, ontology);
    const ImageBaselineResult b = evaluate_image_baseline(seq.images, source, queries, ontology);
    EXPECT_GT(e.cells_with_points, 1000u);
    EXPECT_GT(b.images, 10u);
    return Result{*e.report.accuracy, *e.report.hit_rate, *b.matrix.accuracy()};
  };
  // Noisy: half of the cells of each view swapped, mostly with classes of another coarse class.
  const Result normal = run(0.15f, 0.75f), noisy = run(0.5f, 0.25f);
  std::cout << "voxel accuracy / hit rate / per-image baseline: default simulated encoder " << normal.map_accuracy
            << " / " << normal.hit_rate << " / " << normal.baseline_accuracy << "; noisy (confusion 0.5, 25% related) "
            << noisy.map_accuracy << " / " << noisy.hit_rate << " / " << noisy.baseline_accuracy << "\n";
  // End to end on a short drive, ideal text queries: the map labels terrain well.
  EXPECT_GT(normal.map_accuracy, 0.85);
  EXPECT_GT(normal.hit_rate, 0.85);
  // When single views are often wrong, fusing many views into each voxel beats classifying each
  // image on its own; with the gentle default encoder the geometry of projection dominates instead
  // (README, "Evaluation"), so only the noisy case is asserted.
  EXPECT_GT(noisy.map_accuracy, noisy.baseline_accuracy);
  EXPECT_LT(normal.map_accuracy - noisy.map_accuracy, normal.baseline_accuracy - noisy.baseline_accuracy);
}

TEST_F(MappingPipelineTest, CompositeTextQueriesAndPointLookUps) {
  const Sequence seq = read_sequence(dir_);
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  PipelineReport report;
  const SemanticMap map = build_map(seq, &source, options(), report);
  SimulatedTextEncoder text(encoder_config());
  auto vec = [&](const char* t) {
    const auto v = text.encode(t);
    return Eigen::VectorXf(Eigen::Map<const Eigen::VectorXf>(v.data(), static_cast<Eigen::Index>(v.size())));
  };
  const Ontology ontology = Ontology::builtin("rellis3d-coarse");
  const QuerySet queries = text_queries(encoder_config(), ontology);
  const int rough = *queries.find("rough"), obstacle = *queries.find("obstacle");

  // Grass plus dirt minus tree (paper Figure 6.2): the best voxels are terrain, none an obstacle.
  const Eigen::VectorXf q = composite_query({vec("grass"), vec("dirt")}, {vec("tree")});
  SearchOptions search;
  search.top_k = 200;
  const auto found = similarity_search(map, {q.data(), static_cast<std::size_t>(q.size())}, search);
  ASSERT_EQ(found.size(), 200u);
  for (std::size_t i = 1; i < found.size(); ++i) EXPECT_GE(found[i - 1].score, found[i].score);
  std::vector<Vec3d> points;
  for (const ScoredCell& c : found) points.push_back(c.position_world);
  const auto answers = query_points(map, points, &queries);
  // Search results carry what a point look-up gives at their cell: statistics, and with a query
  // set the class and its confidence.
  std::vector<ScoredCell> classified = found;
  classify_results(map, queries, classified);
  std::size_t terrain = 0;
  for (std::size_t i = 0; i < answers.size(); ++i) {
    ASSERT_TRUE(answers[i].found);
    EXPECT_EQ(answers[i].cell, found[i].cell);
    EXPECT_EQ(answers[i].count, found[i].count);
    EXPECT_FALSE(found[i].match);
    EXPECT_FLOAT_EQ(found[i].stats.weight, answers[i].stats.weight);
    EXPECT_NEAR(found[i].stats.spread, answers[i].stats.spread, 1e-3f * (1.f + answers[i].stats.spread));
    ASSERT_TRUE(classified[i].match);
    if (answers[i].match->margin > 1e-3f) {
      EXPECT_EQ(classified[i].match->class_index, answers[i].match->class_index);
    }
    EXPECT_NEAR(classified[i].confidence, answers[i].confidence, 1e-3f);
    terrain += answers[i].match->class_index == rough;
    EXPECT_NE(answers[i].match->class_index, obstacle);
  }
  EXPECT_GT(terrain, 180u);
  // Its threshold form keeps exactly the cells at or above the score.
  search.top_k = 0;
  search.threshold = found[99].score;
  EXPECT_GE(similarity_search(map, {q.data(), static_cast<std::size_t>(q.size())}, search).size(), 100u);

  // Looking up points: an empty place has no answer; a voxel's embedding is its stored mean.
  const auto nothing = query_points(map, std::vector<Vec3d>{Vec3d(1e5, 0, 0)});
  EXPECT_FALSE(nothing[0].found);
  // A query set of another dimension is refused.
  QuerySet wrong = queries;
  wrong.vectors = QueryMatrix::Ones(queries.size(), 32);
  EXPECT_THROW(classify_map(map, wrong), Error);
  EXPECT_THROW(similarity_search(map, std::vector<float>(32, 1.0f)), Error);
}

TEST_F(MappingPipelineTest, ClassifiedCellsCarryTheirStatisticsAndConfidence) {
  const Sequence seq = read_sequence(dir_);
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  PipelineReport report;
  PipelineOptions short_submaps = options();
  short_submaps.map.submap_length = 4.0;  // neighbouring submaps share cells
  const SemanticMap map = build_map(seq, &source, short_submaps, report);
  const QuerySet queries = text_queries(encoder_config(), Ontology::builtin("rellis3d-coarse"));
  const std::vector<ClassifiedCell> cells = classify_map(map, queries);
  std::vector<Vec3d> centres;
  for (const ClassifiedCell& c : cells) centres.push_back(c.position_world);
  const auto answers = query_points(map, centres, &queries);
  std::size_t shared = 0, spread = 0;
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const ClassifiedCell& c = cells[i];
    ASSERT_TRUE(answers[i].found);
    // The paper's rule weighs each view 1; classify folds two submaps' entries by Chan's rule on
    // their means, the point look-up about the fp32 mean: the same statistics.
    EXPECT_FLOAT_EQ(c.stats.weight, static_cast<float>(c.count));
    EXPECT_NEAR(c.stats.spread, answers[i].stats.spread, 1e-3f * (1.f + answers[i].stats.spread));
    EXPECT_EQ(c.confidence, voxel_confidence(c.match, c.count, c.stats));
    EXPECT_NEAR(answers[i].confidence, c.confidence, 1e-3f);
    EXPECT_GE(c.confidence, 0.f);
    EXPECT_LE(c.confidence, 1.f);
    shared += answers[i].entries > 1;
    spread += c.stats.spread > 0.f;
  }
  EXPECT_GT(shared, 10u);  // cells two submaps share are checked too
  EXPECT_GT(spread, cells.size() / 2);
}

}  // namespace
}  // namespace slamvdb
