#include "slamvdb/eval/confusion_png.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

TEST(ConfusionPng, CellsAreColouredByTheRowShare) {
  ConfusionMatrix m({"smooth", "rough", "void"}, {2});
  m.add(0, 0, 90);
  m.add(0, 1, 10);
  m.add(1, 1, 50);
  m.add(1, 2, 50);  // predicted void (rule off): a column of its own
  m.add(2, 0, 7);   // ignored row: not drawn
  const cv::Mat img = render_confusion_matrix(m, "test");
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.type(), CV_8UC3);

  // Colours present: viridis at 90%, 10%, 50% and 0%.
  const auto viridis = [](double share) {
    cv::Mat v(1, 1, CV_8UC1, cv::Scalar(static_cast<int>(share * 255 + 0.5))), c;
    cv::applyColorMap(v, c, cv::COLORMAP_VIRIDIS);
    return c.at<cv::Vec3b>(0, 0);
  };
  const auto pixels_of = [&](cv::Vec3b colour) {
    cv::Mat mask;
    cv::inRange(img, cv::Scalar(colour[0], colour[1], colour[2]), cv::Scalar(colour[0], colour[1], colour[2]), mask);
    return cv::countNonZero(mask);
  };
  for (double share : {0.9, 0.1, 0.5}) EXPECT_GT(pixels_of(viridis(share)), 500) << share;
  EXPECT_GT(pixels_of(viridis(0.0)), 500);  // rough -> smooth is 0 %

  testing::TempDir dir;
  write_confusion_png(dir.path / "cm.png", m, "test");
  const cv::Mat back = cv::imread((dir.path / "cm.png").string());
  EXPECT_EQ(back.size(), img.size());
  EXPECT_NE(testing::error_of([&] { write_confusion_png(dir.path / "no" / "cm.png", m); }).find("cannot write"),
            std::string::npos);
}

}  // namespace
}  // namespace slamvdb
