#include "slamvdb/io/rellis_reader.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/tiny_rellis.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/io/scan_io.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

const fs::path kFixture = fs::path(SLAMVDB_SOURCE_DIR) / "../shared/fixtures/rellis3d-000104";
constexpr std::array<double, 5> kPublishedDistortion{-0.134313, -0.025905, 0.002181, 0.00084, 0.0};

using testing::TempDir;

using testing::error_of;

// ---- the real frame 000104 ----

class RellisFixture : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scan = new LidarScan(read_scan({0, kFixture / "000104.bin", kFixture / "000104.label"}));
    stats = drop_invalid_points(*scan, 0.0f);
    labels =
        new cv::Mat(load_image_frame({0, {}, kFixture / "frame000104-1581624663_149.png", {}}, false, true).labels);
  }
  static void TearDownTestSuite() {
    delete scan;
    delete labels;
  }
  static CameraModel camera() {
    return read_rellis_camera_info(kFixture / "camera_info.txt",
                                   read_image_size(kFixture / "frame000104-1581624663_149.jpg"));
  }

  struct Agreement {
    std::size_t in_image = 0, agreeing = 0;
    double fraction() const { return in_image ? static_cast<double>(agreeing) / in_image : 0.0; }
  };
  // Projects every labelled (non-void) point and compares its class with the 2D label image.
  static Agreement agreement(const CameraModel& cam, const Pose& T_camera_lidar) {
    Agreement a;
    for (std::size_t i = 0; i < scan->points.size(); ++i) {
      if (scan->labels[i] == 0) continue;
      const Vec3d p = T_camera_lidar * scan->points[i].cast<double>();
      // Beyond about 52 degrees off-axis the published polynomial folds back and would map points
      // far outside the field of view into the image; stay well inside (the image corners are 22 degrees
      // off-axis).
      if (p.z() <= 0 || p.head<2>().norm() > p.z()) continue;
      const auto uv = cam.project(p);
      if (!uv) continue;
      const int u = static_cast<int>(std::floor(uv->x() + 0.5)), v = static_cast<int>(std::floor(uv->y() + 0.5));
      if (u < 0 || v < 0 || u >= cam.width || v >= cam.height) continue;
      ++a.in_image;
      a.agreeing += labels->at<uint8_t>(v, u) == scan->labels[i];
    }
    return a;
  }

  static inline LidarScan* scan = nullptr;
  static inline ScanFilterStats stats;
  static inline cv::Mat* labels = nullptr;
};

TEST_F(RellisFixture, ScanHasTheDocumentedNoReturnPoints) {
  EXPECT_EQ(stats.input, 131072u);
  EXPECT_EQ(stats.no_return, 53364u);
  EXPECT_EQ(stats.non_finite, 0u);
  EXPECT_EQ(scan->points.size(), 131072u - 53364u);
  EXPECT_EQ(scan->labels.size(), scan->points.size());
}

TEST_F(RellisFixture, CalibrationFilesParse) {
  const CameraModel cam = camera();
  EXPECT_EQ(cam.width, 1920);
  EXPECT_EQ(cam.height, 1200);
  EXPECT_DOUBLE_EQ(cam.fx, 2813.643275);
  EXPECT_DOUBLE_EQ(cam.cy, 624.049972);
  EXPECT_FALSE(cam.has_distortion());
  const Pose T = read_rellis_transforms(kFixture / "transforms.yaml");
  EXPECT_TRUE(T.translation().isApprox(Vec3d(-0.13165462, 0.03870398, -0.17253834)));
  // The camera looks along the LiDAR's -x axis (the Ouster sensor frame's x points to its connector).
  EXPECT_LT((T.linear() * Vec3d::UnitZ()).x(), -0.99);
}

TEST_F(RellisFixture, InverseExtrinsicsProjectPointsOntoMatchingLabels) {
  const Pose T_lidar_camera = read_rellis_transforms(kFixture / "transforms.yaml");
  const Agreement right = agreement(camera(), T_lidar_camera.inverse());
  EXPECT_GT(right.in_image, 6000u);
  EXPECT_LT(right.in_image, 9000u);
  EXPECT_GT(right.fraction(), 0.70) << right.agreeing << " of " << right.in_image;

  const Agreement wrong = agreement(camera(), T_lidar_camera);  // the classic convention mistake
  EXPECT_LT(wrong.fraction(), 0.05) << wrong.agreeing << " of " << wrong.in_image;

  CameraModel distorted = camera();
  distorted.distortion = kPublishedDistortion;
  const Agreement with_distortion = agreement(distorted, T_lidar_camera.inverse());
  EXPECT_GT(with_distortion.fraction(), 0.70) << with_distortion.agreeing << " of " << with_distortion.in_image;
}

TEST_F(RellisFixture, ProjectionMatchesOpenCvProjectPoints) {
  CameraModel cam = camera();
  cam.distortion = kPublishedDistortion;
  const Pose T_camera_lidar = read_rellis_transforms(kFixture / "transforms.yaml").inverse();
  std::vector<cv::Point3d> points;
  std::vector<Eigen::Vector2d> ours;
  for (const Vec3f& p : scan->points) {
    const Vec3d pc = T_camera_lidar * p.cast<double>();
    const auto uv = cam.project(pc);
    if (!uv || uv->x() < 0 || uv->y() < 0 || uv->x() > cam.width || uv->y() > cam.height) continue;
    points.emplace_back(pc.x(), pc.y(), pc.z());
    ours.push_back(*uv);
  }
  ASSERT_GT(points.size(), 6000u);
  const cv::Matx33d K(cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  std::vector<cv::Point2d> theirs;
  cv::projectPoints(points, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K,
                    std::vector<double>(cam.distortion.begin(), cam.distortion.end()), theirs);
  double max_difference = 0.0;
  for (std::size_t i = 0; i < points.size(); ++i)
    max_difference = std::max(max_difference, (ours[i] - Eigen::Vector2d(theirs[i].x, theirs[i].y)).norm());
  EXPECT_LT(max_difference, 1e-6);
}

// ---- tiny synthetic layouts ----

TEST(RellisImageName, ParsesFrameAndDecimalFraction) {
  const auto a = parse_rellis_image_name("frame000104-1581624663_149");
  ASSERT_TRUE(a);
  EXPECT_EQ(a->frame, 104);
  EXPECT_DOUBLE_EQ(a->stamp, 1581624663.149);
  EXPECT_DOUBLE_EQ(parse_rellis_image_name("frame7-100_5")->stamp, 100.5);
  EXPECT_DOUBLE_EQ(parse_rellis_image_name("frame7-100_05")->stamp, 100.05);
  for (const char* bad : {"000104", "frame000104", "frame000104-1581624663", "frameX-1_2", "frame1-2_3a", "frame1-_3"})
    EXPECT_FALSE(parse_rellis_image_name(bad)) << bad;
}

using testing::TinyRellis;
using testing::has_note;

TEST(RellisReader, PairsScansWithCameraFramesWithoutTimesTxt) {
  TempDir tmp;
  TinyRellis{}.write(tmp.path);
  const Sequence seq = read_rellis_sequence(tmp.path);
  EXPECT_EQ(seq.layout, "rellis3d");
  ASSERT_EQ(seq.scans.size(), 3u);
  EXPECT_DOUBLE_EQ(seq.scans[0].stamp, 1000.5);
  EXPECT_DOUBLE_EQ(seq.scans[1].stamp, 1000.6);
  EXPECT_NEAR(seq.scans[2].stamp, 1000.7, 1e-9);  // no frame000002: extrapolated at the frame period
  EXPECT_TRUE(has_note(seq, "frameNNNNNN")) << fmt::format("{}", fmt::join(seq.notes, "\n"));
  EXPECT_TRUE(has_note(seq, "1 of 3 scans had no frame"));
  EXPECT_EQ(seq.scans[1].points.filename(), "000001.bin");
  EXPECT_EQ(seq.scans[1].labels.filename(), "000001.label");

  ASSERT_EQ(seq.images.size(), 2u);
  EXPECT_DOUBLE_EQ(seq.images[1].stamp, 1000.6);
  EXPECT_EQ(seq.images[1].rgb.filename(), "frame000001-1000_6.jpg");
  EXPECT_EQ(seq.images[1].labels.filename(), "frame000001-1000_6.png");
  EXPECT_TRUE(seq.images[1].features.empty());
  EXPECT_TRUE(has_note(seq, "2 of 2 images have no feature map"));

  EXPECT_EQ(seq.camera.width, 32);
  EXPECT_EQ(seq.camera.height, 24);
  EXPECT_DOUBLE_EQ(seq.camera.fy, 21);
  const Eigen::Quaterniond q(0.5, -0.5, 0.5, -0.5);
  EXPECT_TRUE(seq.T_lidar_camera.linear().isApprox(q.toRotationMatrix()));
  EXPECT_TRUE(seq.T_lidar_camera.translation().isApprox(Vec3d(0.1, 0.2, 0.3)));

  ASSERT_EQ(seq.poses.size(), 3u);
  EXPECT_DOUBLE_EQ(seq.poses.stamps()[2], seq.scans[2].stamp);
  EXPECT_DOUBLE_EQ(seq.poses.poses()[2].translation().x(), 2.0);
}

TEST(RellisReader, InterpolatesScansBetweenPairedFrames) {
  TempDir tmp;
  TinyRellis layout;
  layout.scans = {0, 1, 2, 3};
  layout.images = {{0, "10_0"}, {3, "10_9"}};
  layout.poses = 4;
  layout.write(tmp.path);
  const Sequence seq = read_rellis_sequence(tmp.path);
  EXPECT_NEAR(seq.scans[1].stamp, 10.3, 1e-9);
  EXPECT_NEAR(seq.scans[2].stamp, 10.6, 1e-9);
}

TEST(RellisReader, UsesTimesTxtWhenPresent) {
  TempDir tmp;
  TinyRellis layout;
  layout.times = {5.0, 5.1, 5.25};
  layout.write(tmp.path);
  const Sequence seq = read_rellis_sequence(tmp.path);
  EXPECT_DOUBLE_EQ(seq.scans[2].stamp, 5.25);
  EXPECT_DOUBLE_EQ(seq.images[0].stamp, 1000.5);  // images keep the stamps of their names
  EXPECT_FALSE(has_note(seq, "frameNNNNNN"));
}

TEST(RellisReader, RejectsInconsistentFilesNamingThem) {
  {
    TempDir tmp;
    TinyRellis layout;
    layout.times = {5.0, 4.0, 6.0};
    layout.write(tmp.path);
    const std::string message = error_of([&] { read_rellis_sequence(tmp.path); });
    EXPECT_NE(message.find("times.txt"), std::string::npos) << message;
    EXPECT_NE(message.find("increasing"), std::string::npos) << message;
  }
  {
    TempDir tmp;
    TinyRellis layout;
    layout.times = {5.0, 6.0};
    layout.write(tmp.path);
    EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("has 2 time stamps but"), std::string::npos);
  }
  {
    TempDir tmp;
    TinyRellis layout;
    layout.poses = 2;
    layout.write(tmp.path);
    const std::string message = error_of([&] { read_rellis_sequence(tmp.path); });
    EXPECT_NE(message.find("has 2 poses but"), std::string::npos) << message;
    EXPECT_NE(message.find("3 scans"), std::string::npos) << message;
  }
  {
    TempDir tmp;
    TinyRellis layout;
    layout.images = {{10, "1000_5"}, {11, "1000_6"}};  // no frame number matches a scan
    layout.write(tmp.path);
    EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("times.txt"), std::string::npos);
  }
  {
    TempDir tmp;
    TinyRellis{}.write(tmp.path);
    fs::remove(tmp.path / "transforms.yaml");
    EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("transforms.yaml"), std::string::npos);
    fs::remove_all(tmp.path / "os1_cloud_node_kitti_bin");
    EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("os1_cloud_node_kitti_bin"), std::string::npos);
  }
  {
    TempDir tmp;
    TinyRellis{}.write(tmp.path);
    std::ofstream(tmp.path / "pylon_camera_node" / "snapshot.jpg") << "x";
    EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("snapshot.jpg"), std::string::npos);
  }
}

TEST(RellisReader, DistortionFromCameraInfoOrOptions) {
  TempDir tmp;
  TinyRellis layout;
  layout.camera_info = "20 21 16 12\n-0.1 0.01 0.001 0.002 0\n";
  layout.write(tmp.path);
  EXPECT_DOUBLE_EQ(read_rellis_sequence(tmp.path).camera.distortion[0], -0.1);

  ReadOptions options;
  options.distortion = kPublishedDistortion;
  const Sequence seq = read_sequence(tmp.path, options);
  EXPECT_EQ(seq.layout, "rellis3d");
  EXPECT_EQ(seq.camera.distortion, kPublishedDistortion);
  EXPECT_TRUE(has_note(seq, "given by the user"));

  std::ofstream(tmp.path / "camera_info.txt") << "20 21 16\n";
  EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("fx fy cx cy"), std::string::npos);
}

TEST(RellisReader, LabelImagesAloneAreEnough) {
  TempDir tmp;
  TinyRellis{}.write(tmp.path);
  fs::remove(tmp.path / "pylon_camera_node" / "frame000000-1000_5.jpg");
  const Sequence partial = read_rellis_sequence(tmp.path);
  ASSERT_EQ(partial.images.size(), 2u);
  EXPECT_TRUE(partial.images[0].rgb.empty());
  EXPECT_EQ(partial.images[0].labels.filename(), "frame000000-1000_5.png");
  EXPECT_TRUE(has_note(partial, "1 of 2 images have a label image but no camera image"));

  fs::remove_all(tmp.path / "pylon_camera_node");
  const Sequence labels_only = read_rellis_sequence(tmp.path);
  EXPECT_EQ(labels_only.images.size(), 2u);
  EXPECT_EQ(labels_only.camera.width, 32);  // size from the first label image
  fs::remove_all(tmp.path / "pylon_camera_node_label_id");
  EXPECT_NE(error_of([&] { read_rellis_sequence(tmp.path); }).find("pylon_camera_node"), std::string::npos);
}

TEST(RellisReader, FindsFeatureMapsByImageStem) {
  TempDir tmp;
  TinyRellis{}.write(tmp.path);
  std::ofstream(tmp.path / "features" / "frame000001-1000_6.npy") << "x";
  const Sequence seq = read_rellis_sequence(tmp.path);
  EXPECT_TRUE(seq.images[0].features.empty());
  EXPECT_EQ(seq.images[1].features.filename(), "frame000001-1000_6.npy");
  EXPECT_TRUE(has_note(seq, "1 of 2 images have no feature map"));
}

}  // namespace
}  // namespace slamvdb
