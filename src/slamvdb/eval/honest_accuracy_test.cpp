// Issue 22 on a short SIMULATED drive with the realistic encoder: the per-image baseline is clearly
// below the clean encoder's, the fused map beats it and the single-view voxel baseline on voxel
// accuracy and mIoU, quality weighting does not lose to the paper's plain running mean, and
// the most confident half of the voxels is the more accurate. Everything is computed once (one
// drive, five scorings) and asserted by the tests below. The queries are class means of the first
// half's features; images and scans of the second half are scored.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <map>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/eval/image_baseline.hpp"
#include "slamvdb/eval/label_images.hpp"
#include "slamvdb/eval/map_evaluation.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/query/class_confidence.hpp"
#include "slamvdb/synth/sequence_writer.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

struct HonestScores {
  double accuracy = 0, miou = 0;
  std::vector<CoveragePoint> coverage{};  // maps only: ranked by voxel_confidence
  std::vector<CoveragePoint> spread_coverage{};  // ranked with voxel_confidence's spread factor on
};

class HonestAccuracyTest : public ::testing::Test {
 protected:
  static SimulatedEncoderConfig encoder(const char* preset) {
    SimulatedEncoderConfig base;
    base.dim = 64;
    return simulated_encoder_preset(preset, base);
  }
  static HonestScores scores(const ConfusionMatrix& m) { return {*m.accuracy(), *m.mean_iou(), {}}; }

  static QuerySet class_mean_queries(const std::vector<ImageRecord>& images, const Ontology& ontology) {
    EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder("realistic")),
                                EncoderFeatureSource::Input::kLabels);
    const LabelMapping target = ontology.training_targets();
    const int dim = encoder("realistic").dim, k = ontology.num_classes();
    std::vector<float> sum(static_cast<std::size_t>(k) * dim, 0.f);
    std::vector<std::size_t> n(k, 0);
    for (const ImageRecord& rec : images) {
      const FeatureMap f = source.features_for(rec);
      const std::vector<uint16_t> labels = read_labels_at(rec.labels, f.width(), f.height());
      for (std::size_t p = 0; p < f.pixels(); ++p) {
        const int c = target(labels[p]);
        if (c < 0) continue;
        kernels::add(sum.data() + static_cast<std::size_t>(c) * dim, f.view(p), static_cast<std::size_t>(dim));
        ++n[c];
      }
    }
    SimulatedTextEncoder text(encoder("realistic"));
    QueryMatrix v(k, dim);
    for (int c = 0; c < k; ++c)
      v.row(c) = n[c] > 0 ? Eigen::Map<const Eigen::RowVectorXf>(sum.data() + static_cast<std::size_t>(c) * dim, dim)
                          : Eigen::Map<const Eigen::RowVectorXf>(text.encode(ontology.classes()[c].name).data(), dim);
    return make_query_set(ontology, v, text.model_id());
  }

  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("slamvdb_honest_accuracy_test_" + std::to_string(::getpid()));
    synth::SynthConfig config;
    config.seed = 3;
    config.length_m = 40.0;
    config.image_width = 320;
    config.image_height = 200;
    synth::write_synthetic_sequence(config, dir_, true);
    const Sequence seq = read_sequence(dir_);
    const Ontology ontology = Ontology::builtin("rellis3d-coarse");
    // Queries: each coarse class's mean realistic feature over the first half's labelled pixels
    // (what training converges towards; the ideal text embeddings ignore the encoder's biases).
    const std::size_t half = seq.images.size() / 2;
    const std::vector<ImageRecord> first(seq.images.begin(), seq.images.begin() + static_cast<std::ptrdiff_t>(half)),
        second(seq.images.begin() + static_cast<std::ptrdiff_t>(half), seq.images.end());
    const QuerySet queries = class_mean_queries(first, ontology);
    const double t_mid = second.front().stamp;

    for (const char* preset : {"realistic", "clean"}) {
      EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder(preset)),
                                  EncoderFeatureSource::Input::kLabels);
      results_[std::string("per-image ") + preset] =
          scores(evaluate_image_baseline(second, source, queries, ontology, {}).matrix);
    }
    std::vector<GroundTruthScan> scans;
    for (const ScanRecord& rec : seq.scans)
      if (const auto pose = seq.poses.at(rec.stamp); pose && rec.stamp >= t_mid)
        scans.push_back({*pose, [rec] { return read_scan(rec); }, ""});
    for (const FusionWeighting rule : {FusionWeighting::kPaper, FusionWeighting::kQuality, FusionWeighting::kSingleView}) {
      EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder("realistic")),
                                  EncoderFeatureSource::Input::kLabels);
      PipelineOptions options;
      options.fusion.weighting = rule;
      options.map.semantic.dim = 64;
      options.map.semantic.single_view = rule == FusionWeighting::kSingleView;
      PipelineReport report;
      const SemanticMap map = build_map(seq, &source, options, report, {});
      const MapEvaluation e = evaluate_map(map, scans, queries, ontology, {});
      HonestScores s = scores(e.voxels);
      s.coverage = accuracy_coverage(e, {0.5, 1.0});
      // The ranking with the spread factor on (at the median spread), and the median spread S/W.
      const std::vector<ClassifiedCell> cells = classify_map(map, queries);
      MapEvaluation with_spread = e;
      std::vector<float> spreads;
      for (MapEvaluation::ScoredVoxel& v : with_spread.scored_voxels) {
        const ClassifiedCell& c = cells[v.cell];
        v.confidence = voxel_confidence(c.match, c.count, c.stats, kMedianSpread);
        if (c.stats.known() && c.stats.weight > 0) spreads.push_back(c.stats.spread / c.stats.weight);
      }
      s.spread_coverage = accuracy_coverage(with_spread, {0.5, 1.0});
      std::nth_element(spreads.begin(), spreads.begin() + static_cast<std::ptrdiff_t>(spreads.size() / 2), spreads.end());
      std::printf("  %-12s median spread S/W %.4f; top half %.2f %% (voxel_confidence), %.2f %% with the spread factor\n",
                  std::string(to_string(rule)).c_str(), spreads.empty() ? 0.0 : spreads[spreads.size() / 2], 100 * s.coverage[0].accuracy,
                  100 * s.spread_coverage[0].accuracy);
      results_[std::string(to_string(rule))] = s;
    }
    for (const auto& [name, s] : results_)
      std::printf("  %-20s accuracy %.2f %%, mIoU %.2f %%\n", name.c_str(), 100 * s.accuracy, 100 * s.miou);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static fs::path dir_;
  static std::map<std::string, HonestScores> results_;
};
fs::path HonestAccuracyTest::dir_;
std::map<std::string, HonestScores> HonestAccuracyTest::results_;

TEST_F(HonestAccuracyTest, PerImageBaselineIsInTheRealisticBand) {
  // The default drive with trained queries is calibrated to 75-85 % (README, "Honest accuracy";
  // measured by `demo`, not here). This short drive at a low resolution with class-mean queries
  // sits lower, hence a wider band; the realistic encoder must err clearly more than the clean one.
  const double realistic = results_.at("per-image realistic").accuracy, clean = results_.at("per-image clean").accuracy;
  EXPECT_GT(realistic, 0.60);
  EXPECT_LT(realistic, 0.85);
  EXPECT_GT(clean, realistic + 0.05);
}

TEST_F(HonestAccuracyTest, FusedMapBeatsPerImageAndSingleView) {
  const HonestScores image = results_.at("per-image realistic"), single = results_.at("single-view");
  for (const char* rule : {"paper", "quality"}) {  // the default rule first
    SCOPED_TRACE(rule);
    const HonestScores map = results_.at(rule);
    EXPECT_GT(map.accuracy, image.accuracy + 0.02);
    EXPECT_GT(map.miou, image.miou);
    EXPECT_GT(map.accuracy, single.accuracy + 0.02);
    EXPECT_GT(map.miou, single.miou + 0.02);
  }
}

TEST_F(HonestAccuracyTest, QualityWeightingDoesNotLoseToThePaperRule) {
  // Measured on this drive: +0.01 points of accuracy, +0.25 of mIoU (seeds 1 and 2 of the same
  // drive: -0.08 / 0.00 and +0.41 / +0.31). The first shapes lost 0.5 points here (projective_fusion.hpp).
  const HonestScores quality = results_.at("quality"), paper = results_.at("paper");
  EXPECT_GE(quality.accuracy, paper.accuracy - 0.002);
  EXPECT_GE(quality.miou, paper.miou - 0.002);
}

TEST_F(HonestAccuracyTest, TheMostConfidentHalfOfTheVoxelsIsMoreAccurateThanTheRest) {
  for (const char* rule : {"quality", "paper"}) {
    const std::vector<CoveragePoint>& c = results_.at(rule).coverage;
    ASSERT_EQ(c.size(), 2u);
    const double half = c[0].accuracy, all = c[1].accuracy;
    const double rest = (all * c[1].voxels - half * c[0].voxels) / static_cast<double>(c[1].voxels - c[0].voxels);
    EXPECT_GT(half, rest + 0.05) << rule;
  }
}

}  // namespace
}  // namespace slamvdb
