// The real RELLIS-3D frame (../shared/fixtures/rellis3d-000104: one real scan, one real image, real
// labels) mapped from its own image with the SIMULATED encoder fed the real label image, and the map
// scored against the scan's own labels (paper protocol), as `map` + `eval` do with their defaults and
// text queries of the coarse class names (`embed-text --simulated` + `import-queries`). Before issue
// 22 (the clean encoder, the paper's rule) this scored 79.52 % voxel accuracy and 51.34 % mIoU
// (measured with the binary of that time; README "Honest accuracy"): the mapping must still do at
// least as well, and quality weighting, which on one view with no SIMULATED view geometry differs
// from the paper's rule only by its depth-edge and border weights, must not lose to it.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <map>

#include "slamvdb/eval/map_evaluation.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

const fs::path kRellisFrame = fs::path(SLAMVDB_SOURCE_DIR) / "../shared/fixtures/rellis3d-000104";

struct FrameScores {
  double accuracy = 0, hit_rate = 0, miou = 0;
};

// The fixture's files in the RELLIS-3D layout (one scan, its image, one identity pose).
void write_rellis_frame_sequence(const fs::path& dir) {
  const std::pair<const char*, fs::path> files[] = {
      {"000104.bin", "os1_cloud_node_kitti_bin/000000.bin"},
      {"000104.label", "os1_cloud_node_semantickitti_label_id/000000.label"},
      {"frame000104-1581624663_149.jpg", "pylon_camera_node/frame000000-1581624663_149.jpg"},
      {"frame000104-1581624663_149.png", "pylon_camera_node_label_id/frame000000-1581624663_149.png"},
      {"camera_info.txt", "camera_info.txt"},
      {"transforms.yaml", "transforms.yaml"}};
  for (const auto& [from, to] : files) {
    fs::create_directories((dir / to).parent_path());
    fs::copy_file(kRellisFrame / from, dir / to);
  }
  std::ofstream(dir / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n";
  std::ofstream(dir / "times.txt") << "1581624663.149\n";
}

class RellisFrameTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(kRellisFrame / "000104.bin")) return;
    dir_ = fs::temp_directory_path() / ("slamvdb_rellis_frame_test_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    write_rellis_frame_sequence(dir_);
    const Sequence seq = read_sequence(dir_);
    const Ontology ontology = Ontology::builtin("rellis3d-coarse");
    std::vector<GroundTruthScan> scans;
    for (const ScanRecord& rec : seq.scans)
      scans.push_back({*seq.poses.at(rec.stamp), [rec] { return read_scan(rec); }, "000104"});
    for (const char* preset : {"clean", "realistic"}) {
      const SimulatedEncoderConfig sim = simulated_encoder_preset(preset, {});
      // The coarse class names' SIMULATED text embeddings (what import-queries makes of embed-text's).
      SimulatedTextEncoder text(sim);
      QueryMatrix vectors(ontology.num_classes(), sim.dim);
      for (int c = 0; c < ontology.num_classes(); ++c)
        vectors.row(c) = Eigen::Map<const Eigen::RowVectorXf>(text.encode(ontology.classes()[c].name).data(), sim.dim);
      const QuerySet queries = make_query_set(ontology, vectors, text.model_id());
      for (const FusionWeighting rule : {FusionWeighting::kPaper, FusionWeighting::kQuality}) {
        EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(sim), EncoderFeatureSource::Input::kLabels);
        PipelineOptions options;
        options.fusion.weighting = rule;
        PipelineReport report;
        const SemanticMap map = build_map(seq, &source, options, report, {});
        const MapEvaluation e = evaluate_map(map, scans, queries, ontology, {});
        scores_[fmt::format("{} {}", preset, to_string(rule))] = {*e.report.accuracy, *e.report.hit_rate, *e.report.miou};
      }
    }
    for (const auto& [name, s] : scores_)
      std::printf("  real frame, %-18s voxel accuracy %.2f %%, hit rate %.2f %%, mIoU %.2f %%\n", name.c_str(),
                  100 * s.accuracy, 100 * s.hit_rate, 100 * s.miou);
  }

  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  void SetUp() override {
    if (scores_.empty()) GTEST_SKIP() << "the real RELLIS-3D frame is not at " << kRellisFrame;
  }

  static inline fs::path dir_;
  static inline std::map<std::string, FrameScores> scores_;
};

TEST_F(RellisFrameTest, ClassifiedAtLeastAsWellAsBeforeTheRealisticEncoder) {
  const FrameScores paper = scores_.at("clean paper");
  EXPECT_GE(paper.accuracy, 0.7952 - 0.005);
  EXPECT_GE(paper.miou, 0.5134 - 0.005);
}

TEST_F(RellisFrameTest, QualityWeightingDoesNotLoseOnTheRealFrame) {
  for (const char* preset : {"clean", "realistic"}) {
    SCOPED_TRACE(preset);
    const FrameScores paper = scores_.at(fmt::format("{} paper", preset)),
                      quality = scores_.at(fmt::format("{} quality", preset));
    EXPECT_GE(quality.accuracy, paper.accuracy - 0.005);
    EXPECT_GE(quality.miou, paper.miou - 0.005);
  }
}

TEST_F(RellisFrameTest, TheRealisticEncoderErrsOnRealLabelsToo) {
  // Real data carry no SIMULATED view geometry: only the base, border, exposure, low-resolution and
  // look-alike errors apply, and they still cost the map accuracy.
  EXPECT_LT(scores_.at("realistic paper").accuracy, scores_.at("clean paper").accuracy - 0.05);
}

}  // namespace
}  // namespace slamvdb
