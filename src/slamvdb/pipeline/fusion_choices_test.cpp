// Fusion choices measured on a SIMULATED sequence: occlusion by other submaps' voxels, and feature
// pixels that are not finite (a network's fp16 overflow, a damaged file) never reaching the map.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <limits>

#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/pipeline_fixture.hpp"

namespace slamvdb {
namespace {
using testing::MappingPipelineTest;

TEST_F(MappingPipelineTest, OcclusionByOtherSubmapsIsAMeasuredChoice) {
  const Sequence seq = read_sequence(dir_);
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  PipelineOptions o = options();
  o.map.submap_length = 10.0;
  double acc[2];
  std::size_t cells[2], other[2];
  for (const bool all : {false, true}) {
    o.fusion.occlusion_from_other_submaps = all;
    PipelineReport report;
    const SemanticMap m = build_map(seq, &source, o, report);
    const Correct c = correctness(m, seq);
    acc[all] = accuracy(c, c);
    cells[all] = c.size();
    other[all] = report.fusion.pixels_other_submaps;
  }
  std::cout << "voxel accuracy with occlusion by the active submap only: " << acc[0] << " over " << cells[0]
            << " cells; also by the other submaps: " << acc[1] << " over " << cells[1] << " cells ("
            << other[1] << " pixels taken by other submaps' voxels)\n";
  EXPECT_EQ(other[0], 0u);
  EXPECT_GT(other[1], 0u);
  EXPECT_GT(acc[0], 0.7);
  EXPECT_GT(acc[1], 0.7);
}

// Wraps a feature source and damages some of its feature maps.
struct DamagingSource : FeatureSource {
  FeatureSource& inner;
  std::function<void(const ImageRecord&, FeatureMap&)> damage;
  DamagingSource(FeatureSource& s, std::function<void(const ImageRecord&, FeatureMap&)> d) : inner(s), damage(std::move(d)) {}
  FeatureMap features_for(const ImageRecord& r) override {
    FeatureMap f = inner.features_for(r);
    damage(r, f);
    return f;
  }
  std::string model_id() const override { return inner.model_id(); }
};

// Equal embeddings are finite ones too: NaN equals nothing.
TEST_F(MappingPipelineTest, APoisonedFrameLeavesEveryVoxelAsWithoutIt) {
  const Sequence seq = read_sequence(dir_);
  EncoderFeatureSource clean(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                             EncoderFeatureSource::Input::kLabels);
  PipelineOptions o = options();
  o.max_scans = 40;
  const double poisoned_stamp = seq.images[6].stamp;
  const auto nan = std::numeric_limits<float>::quiet_NaN();

  // A whole frame of NaN (fp16 overflow everywhere): refused and counted; the map is the map
  // built without that image.
  DamagingSource all_nan(clean, [&](const ImageRecord& r, FeatureMap& f) {
    if (r.stamp == poisoned_stamp) std::fill(f.values().begin(), f.values().end(), nan);
  });
  PipelineReport poisoned_report, without_report;
  const SemanticMap poisoned = build_map(seq, &all_nan, o, poisoned_report);
  Sequence without = seq;
  without.images.erase(without.images.begin() + 6);
  const SemanticMap reference = build_map(without, &clean, o, without_report);
  EXPECT_EQ(poisoned_report.fusion.frames_refused_invalid, 1u);
  EXPECT_EQ(poisoned_report.images_failed, 1u);
  EXPECT_NE(poisoned_report.summary().find("1 frames refused"), std::string::npos) << poisoned_report.summary();
  testing::expect_same_index_cells(poisoned, reference);

  // A few pixels of each frame with NaN, Inf or all-zero vectors: those pixels are skipped and
  // counted by reason; the map equals the one where the same pixels carried nothing (zeros).
  auto damage_some = [&](float value, bool whole_vector) {
    return [=](const ImageRecord&, FeatureMap& f) {
      for (int y = 0; y < f.height(); y += 7)
        for (int x = 0; x < f.width(); x += 5) {
          float* p = f.pixel(x, y);
          if (whole_vector) std::fill_n(p, f.dim(), value);
          else p[f.dim() / 2] = value;
        }
    };
  };
  DamagingSource some_nan(clean, damage_some(nan, false)), some_inf(clean, damage_some(INFINITY, false)),
      some_zero(clean, damage_some(0.0f, true));
  PipelineReport r_nan, r_inf, r_zero;
  const SemanticMap m_nan = build_map(seq, &some_nan, o, r_nan);
  const SemanticMap m_inf = build_map(seq, &some_inf, o, r_inf);
  const SemanticMap m_zero = build_map(seq, &some_zero, o, r_zero);
  EXPECT_GT(r_nan.fusion.pixels_nonfinite, 0u);
  EXPECT_EQ(r_nan.fusion.pixels_nonfinite, r_inf.fusion.pixels_nonfinite);
  EXPECT_EQ(r_zero.fusion.pixels_zero, r_nan.fusion.pixels_nonfinite);
  EXPECT_EQ(r_nan.fusion.frames_refused_invalid, 0u);
  testing::expect_same_index_cells(m_nan, m_zero);
  testing::expect_same_index_cells(m_inf, m_zero);
}

}  // namespace
}  // namespace slamvdb
