#include "slamvdb/synth/camera_sim.hpp"

#include <gtest/gtest.h>

#include <iostream>
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

// The view geometry image: range and incidence of the surface along each pixel ray, and a
// world-fixed appearance value that is about standard normal, smooth over a few metres and the same
// from every viewpoint.
TEST(SynthCamera, ViewGeometryIsTheSceneAlongEachPixelRay) {
  SynthConfig config;
  config.length_m = 10.0;
  const SynthWorld world = build_synthetic_world(config);
  const CameraSimulator sim(rellis_camera(160, 100));
  const Pose T = world.T_world_camera(world.camera_stamps_ms[1] / 1000.0);
  RenderOptions options;
  options.view_geometry = true;
  const RenderedFrame frame = sim.render(*world.scene, T, 200.0, options);
  ASSERT_EQ(frame.view.type(), CV_16UC3);
  for (int v = 0; v < 100; v += 7)
    for (int u = 0; u < 160; u += 9) {
      const Vec3d dir = T.linear() * sim.ray(u, v);
      const auto hit = world.scene->raycast(T.translation(), dir, 200.0);
      const auto& g = frame.view.at<cv::Vec<uint16_t, 3>>(v, u);
      if (!hit) {
        EXPECT_EQ(g[0], 0) << u << "," << v;
        continue;
      }
      EXPECT_NEAR(view_range(g[0]), hit->range, 0.006);
      EXPECT_NEAR(view_incidence_cos(g[1]), std::abs(hit->normal.dot(dir)), 1e-4);
      EXPECT_NEAR(view_appearance(g[2]), world_appearance(T.translation() + hit->range * dir, 4.0, 1), 2e-4);
    }
  // Without asking, no view image.
  EXPECT_TRUE(sim.render(*world.scene, T, 200.0).view.empty());

  // The appearance field: mean 0, standard deviation about 1, correlated over half a metre, not over 20 m.
  double sum = 0, sum2 = 0, near = 0, far = 0;
  int n = 0;
  for (int i = 0; i < 200; ++i)
    for (int j = 0; j < 200; ++j) {
      const Vec3d p(i * 1.37, j * 1.91, 0.3 * (i % 5));
      const double a = world_appearance(p, 4.0, 7);
      sum += a, sum2 += a * a, ++n;
      near += a * world_appearance(p + Vec3d(0.5, 0, 0), 4.0, 7);
      far += a * world_appearance(p + Vec3d(20, 0, 0), 4.0, 7);
    }
  const double mean = sum / n, var = sum2 / n - mean * mean;
  std::cout << "world appearance: mean " << mean << ", sd " << std::sqrt(var) << ", corr(0.5 m) " << near / n / var
            << ", corr(20 m) " << far / n / var << "\n";
  EXPECT_NEAR(mean, 0.0, 0.1);
  // 1.28 measured: the interpolated field is not renormalised; the simulated encoder's error rates
  // were calibrated with it as it is.
  EXPECT_NEAR(std::sqrt(var), 1.0, 0.35);
  EXPECT_GT(near / n / var, 0.7);
  EXPECT_LT(std::abs(far / n / var), 0.3);
}

}  // namespace
}  // namespace slamvdb::synth
