#include "slamvdb/eval/coverage_png.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

// A map evaluation whose voxel i of n has confidence (i + 0.5) / n and is right when i >= wrong.
MapEvaluation no_voxels() {
  return {.report = {}, .voxels = ConfusionMatrix({"a"}), .points = ConfusionMatrix({"a"})};
}

MapEvaluation ranked_voxels(std::size_t n, std::size_t wrong) {
  MapEvaluation e = no_voxels();
  for (std::size_t i = 0; i < n; ++i)
    e.scored_voxels.push_back({(static_cast<float>(i) + 0.5f) / static_cast<float>(n), i >= wrong, i});
  return e;
}

TEST(CoveragePng, DrawsEachCurveInItsOwnColour) {
  const std::vector<NamedCoverage> curves = {
      {"paper", accuracy_coverage(ranked_voxels(100, 30), coverage_plot_fractions())},
      {"quality", accuracy_coverage(ranked_voxels(100, 10), coverage_plot_fractions())}};
  ASSERT_EQ(curves[0].curve.size(), 20u);
  EXPECT_DOUBLE_EQ(curves[0].curve.front().accuracy, 1.0);  // the 5 most confident are right
  EXPECT_DOUBLE_EQ(curves[0].curve.back().accuracy, 0.7);
  const cv::Mat img = render_coverage_plot(curves, "test");
  ASSERT_EQ(img.type(), CV_8UC3);
  const auto pixels_of = [&](cv::Scalar rgb) {
    cv::Mat mask;
    cv::inRange(img, rgb, rgb, mask);
    return cv::countNonZero(mask);
  };
  EXPECT_GT(pixels_of({31, 119, 180}), 200);  // first curve (and its legend line)
  EXPECT_GT(pixels_of({255, 127, 14}), 200);  // second curve

  testing::TempDir dir;
  write_coverage_png(dir.path / "coverage.png", curves, "test");
  EXPECT_EQ(cv::imread((dir.path / "coverage.png").string()).size(), img.size());
  EXPECT_NE(testing::error_of([&] { write_coverage_png(dir.path / "no" / "c.png", curves); }).find("cannot write"),
            std::string::npos);
  EXPECT_NE(testing::error_of([&] { render_coverage_plot({}); }).find("no curve"), std::string::npos);
}

TEST(CalibrationTable, BinsVoxelsByConfidenceWithTheirAccuracy) {
  // Voxels at confidence 0.005 .. 0.995; the 30 least confident are wrong.
  const std::vector<CalibrationBin> table = calibration_table(ranked_voxels(100, 30), 10);
  ASSERT_EQ(table.size(), 10u);
  for (const CalibrationBin& b : table) EXPECT_EQ(b.voxels, 10u);
  EXPECT_DOUBLE_EQ(table[0].accuracy, 0.0);
  EXPECT_DOUBLE_EQ(table[3].accuracy, 1.0);
  EXPECT_NEAR(table[9].mean_confidence, 0.95, 1e-6);
  MapEvaluation one = no_voxels();
  one.scored_voxels.push_back({1.0f, true, 0});  // confidence 1 falls in the last bin
  EXPECT_EQ(calibration_table(one, 4)[3].voxels, 1u);
  EXPECT_NE(calibration_markdown(table).find("| 0.9-1.0 | 10 | 0.950 | 100.00 |"), std::string::npos);
  EXPECT_NE(calibration_json(table).find("\"mean_confidence\""), std::string::npos);
}

}  // namespace
}  // namespace slamvdb
