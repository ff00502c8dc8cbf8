#include "slamvdb/io/image_io.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

const fs::path kRellisImages = fs::path(SLAMVDB_SOURCE_DIR) / "../shared/fixtures/rellis3d-000104";

using testing::TempDir;

TEST(ImageIo, SizeFromJpegAndPngHeadersMatchesDecodedImages) {
  for (const char* name : {"frame000104-1581624663_149.jpg", "frame000104-1581624663_149.png"}) {
    EXPECT_EQ(read_image_size(kRellisImages / name), cv::Size(1920, 1200)) << name;
  }
  TempDir tmp;
  const cv::Mat odd(37, 53, CV_8UC3, cv::Scalar(1, 2, 3));
  for (const char* name : {"odd.jpg", "odd.png"}) {
    ASSERT_TRUE(cv::imwrite((tmp.path / name).string(), odd));
    EXPECT_EQ(read_image_size(tmp.path / name), cv::Size(53, 37)) << name;
  }
  // Other formats would have to be decoded to be sized: refused (the readers list PNG and JPEG only).
  ASSERT_TRUE(cv::imwrite((tmp.path / "odd.bmp").string(), odd));
  EXPECT_THROW(read_image_size(tmp.path / "odd.bmp"), Error);
  EXPECT_THROW(read_image_size(tmp.path / "none.png"), Error);
}

TEST(ImageIo, LoadsRgbInRgbOrderAndLabelsAsIds) {
  TempDir tmp;
  const cv::Mat bgr(4, 6, CV_8UC3, cv::Scalar(10, 20, 30));  // B=10 G=20 R=30
  cv::Mat labels(4, 6, CV_8UC1, cv::Scalar(3));
  labels.at<uint8_t>(2, 5) = 17;
  cv::imwrite((tmp.path / "rgb.png").string(), bgr);
  cv::imwrite((tmp.path / "labels.png").string(), labels);

  const ImageFrame frame = load_image_frame({4.5, tmp.path / "rgb.png", tmp.path / "labels.png", {}}, true, true);
  EXPECT_DOUBLE_EQ(frame.stamp, 4.5);
  EXPECT_EQ(frame.source, "rgb.png");
  ASSERT_EQ(frame.rgb.type(), CV_8UC3);
  EXPECT_EQ(frame.rgb.at<cv::Vec3b>(1, 1), cv::Vec3b(30, 20, 10));
  ASSERT_EQ(frame.labels.type(), CV_8UC1);
  EXPECT_EQ(frame.labels.at<uint8_t>(2, 5), 17);
  EXPECT_EQ(frame.labels.at<uint8_t>(0, 0), 3);

  const ImageFrame labels_only = load_image_frame({0, tmp.path / "rgb.png", tmp.path / "labels.png", {}}, false, true);
  EXPECT_TRUE(labels_only.rgb.empty());
  EXPECT_EQ(labels_only.source, "labels.png");
}

TEST(ImageIo, UnreadableOrWrongTypeFilesAreErrors) {
  TempDir tmp;
  std::ofstream(tmp.path / "broken.jpg") << "not an image";
  EXPECT_THROW(load_image_frame({0, tmp.path / "broken.jpg", {}, {}}, true, false), Error);
  EXPECT_THROW(load_image_frame({0, tmp.path / "missing.jpg", {}, {}}, true, false), Error);
  cv::imwrite((tmp.path / "colour_labels.png").string(), cv::Mat(2, 2, CV_8UC3, cv::Scalar(1, 1, 1)));
  try {
    load_image_frame({0, {}, tmp.path / "colour_labels.png", {}}, false, true);
    FAIL() << "a 3-channel label image was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("colour_labels.png"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace slamvdb
