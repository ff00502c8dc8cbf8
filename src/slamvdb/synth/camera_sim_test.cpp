#include "slamvdb/synth/camera_sim.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/synth/world.hpp"

namespace slamvdb::synth {
namespace {

TEST(SynthCamera, RellisIntrinsicsAndMount) {
  const CameraModel full = rellis_camera(1920, 1200);
  EXPECT_DOUBLE_EQ(full.fx, 2813.643275);
  EXPECT_DOUBLE_EQ(full.cy, 624.049972);
  EXPECT_DOUBLE_EQ(full.distortion[0], -0.134313);
  const CameraModel small = rellis_camera(640, 400);
  EXPECT_NEAR(small.fx, 2813.643275 / 3.0, 1e-9);
  EXPECT_NEAR(small.cx, (969.285772 + 0.5) / 3.0 - 0.5, 1e-9);
  // The camera looks along the LiDAR's -x with its y axis down, a few cm from the LiDAR.
  const Pose T = rellis_T_lidar_camera();
  EXPECT_GT(T.linear().col(2).dot(-Vec3d::UnitX()), 0.99);
  EXPECT_GT(T.linear().col(1).dot(-Vec3d::UnitZ()), 0.99);
  EXPECT_LT(T.translation().norm(), 0.3);
}

// Pixel rays must project back onto their pixels with CameraModel::project (the model the
// pipeline uses), and agree with OpenCV's own undistortion.
TEST(SynthCamera, PixelRaysProjectBackOntoTheirPixels) {
  const CameraSimulator sim(rellis_camera(640, 400));
  const CameraModel& cam = sim.camera();
  std::vector<cv::Point2d> pixels, undistorted;
  for (int v = 0; v < cam.height; v += 7)
    for (int u = 0; u < cam.width; u += 9) pixels.emplace_back(u, v);
  for (auto [u, v] : {std::pair{0, 0}, {639, 0}, {0, 399}, {639, 399}}) pixels.emplace_back(u, v);
  const cv::Matx33d K(cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1);
  const std::vector<double> dist(cam.distortion.begin(), cam.distortion.end());
  cv::undistortPoints(pixels, undistorted, K, dist, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-12));
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const int u = static_cast<int>(pixels[i].x), v = static_cast<int>(pixels[i].y);
    const Vec3d& ray = sim.ray(u, v);
    EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
    const auto uv = cam.project(ray);
    ASSERT_TRUE(uv.has_value());
    EXPECT_NEAR(uv->x(), u, 1e-6);
    EXPECT_NEAR(uv->y(), v, 1e-6);
    EXPECT_NEAR(ray.x() / ray.z(), undistorted[i].x, 1e-6);
    EXPECT_NEAR(ray.y() / ray.z(), undistorted[i].y, 1e-6);
  }
  // The distortion is really applied: a corner ray differs from the plain pinhole one.
  const Vec3d& corner = sim.ray(0, 0);
  EXPECT_GT(std::abs(corner.x() / corner.z() - (0 - cam.cx) / cam.fx), 1e-3);
}

TEST(SynthCamera, UninvertibleDistortionIsAnError) {
  CameraModel cam = rellis_camera(640, 400);
  cam.distortion = {-2.0, 0.0, 0.0, 0.0, 0.0};  // folds back inside the image
  EXPECT_THROW(CameraSimulator{cam}, Error);
}

TEST(SynthCamera, LabelImageIsTheSceneAlongEachPixelRay) {
  SynthConfig config;
  config.length_m = 10.0;
  const SynthWorld world = build_synthetic_world(config);
  const CameraSimulator sim(rellis_camera(160, 100));
  const Pose T = world.T_world_camera(world.camera_stamps_ms[1] / 1000.0);
  const RenderedFrame frame = sim.render(*world.scene, T, 200.0);
  ASSERT_EQ(frame.bgr.type(), CV_8UC3);
  ASSERT_EQ(frame.labels.type(), CV_8UC1);
  ASSERT_EQ(frame.labels.cols, 160);
  ASSERT_EQ(frame.labels.rows, 100);
  int sky = 0, ground_below = 0;
  for (int v = 0; v < 100; ++v)
    for (int u = 0; u < 160; ++u) {
      const auto hit = world.scene->raycast(T.translation(), T.linear() * sim.ray(u, v), 200.0);
      ASSERT_EQ(frame.labels.at<uint8_t>(v, u), hit ? hit->label : kSkyClass) << u << "," << v;
      sky += !hit;
      if (v == 99 && hit) ground_below += (hit->label == 10 || hit->label == 1);
    }
  EXPECT_GT(sky, 500);           // the upper part of the image is sky
  EXPECT_GT(ground_below, 100);  // the bottom row is the trail in front of the vehicle
  // Sky is brighter and bluer than the ground; the image has texture, not flat colours.
  const cv::Vec3b top = frame.bgr.at<cv::Vec3b>(0, 80), bottom = frame.bgr.at<cv::Vec3b>(99, 80);
  EXPECT_GT(top[0], top[2]);
  EXPECT_GT(top[0] + top[1] + top[2], bottom[0] + bottom[1] + bottom[2]);
  cv::Scalar mean, stddev;
  cv::meanStdDev(frame.bgr.rowRange(80, 100), mean, stddev);
  EXPECT_GT(stddev[1], 2.0);
}

}  // namespace
}  // namespace slamvdb::synth
