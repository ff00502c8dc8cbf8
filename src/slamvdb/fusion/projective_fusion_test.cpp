#include "slamvdb/fusion/projective_fusion.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/fusion_fixtures.hpp"

namespace slamvdb {
namespace {

CameraModel feature_camera() { return testing::centred_camera(192, 128); }
MapParams params(int dim) { return testing::fusion_map_params(dim); }

// Every pixel's feature is (x, y, 1): the fused value of a voxel is then the mean pixel position.
FeatureMap pixel_coordinate_features(const CameraModel& c) {
  FeatureMap f(3, c.height, c.width);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x) {
      float* p = f.pixel(x, y);
      p[0] = static_cast<float>(x), p[1] = static_cast<float>(y), p[2] = 1.0f;
    }
  return f;
}

void occupy(VoxelMap& map, const Vec3d& p) { map.occupancy().set_log_odds(map.occupancy().key_of(p), 2.0f); }

TEST(ProjectiveFusion, OccludedVoxelReceivesNothing) {
  VoxelMap map(params(3));
  occupy(map, {0.1, 0.1, 5.1});   // in front
  occupy(map, {0.1, 0.1, 10.1});  // straight behind it, with a smaller footprint
  occupy(map, {1.1, 0.1, 10.1});  // behind, but off to the side: visible
  ProjectiveFusion fusion;
  const auto stats = fusion.fuse(map, pixel_coordinate_features(feature_camera()), feature_camera(), Pose::Identity());
  EXPECT_EQ(stats.candidates, 3u);
  EXPECT_EQ(stats.occluded, 1u);
  EXPECT_TRUE(map.semantics().find(map.occupancy().key_of({0.1, 0.1, 5.1})));
  EXPECT_FALSE(map.semantics().find(map.occupancy().key_of({0.1, 0.1, 10.1})));
  EXPECT_TRUE(map.semantics().find(map.occupancy().key_of({1.1, 0.1, 10.1})));
}

TEST(ProjectiveFusion, DepthIsMeasuredFromTheCameraNotTheMapOrigin) {
  // Camera at x = 20 looking back towards the origin along -x.
  Pose T = Pose::Identity();
  T.linear().col(0) = Vec3d(0, 1, 0);
  T.linear().col(1) = Vec3d(0, 0, -1);
  T.linear().col(2) = Vec3d(-1, 0, 0);
  T.translation() = Vec3d(20, 0.1, 0.1);
  VoxelMap map(params(3));
  occupy(map, {15.1, 0.1, 0.1});  // 5 m from the camera, 15 m from the origin
  occupy(map, {5.1, 0.1, 0.1});   // 15 m from the camera, 5 m from the origin
  ProjectiveFusion fusion;
  fusion.fuse(map, pixel_coordinate_features(feature_camera()), feature_camera(), T);
  EXPECT_TRUE(map.semantics().find(map.occupancy().key_of({15.1, 0.1, 0.1})));
  EXPECT_FALSE(map.semantics().find(map.occupancy().key_of({5.1, 0.1, 0.1})));
}

TEST(ProjectiveFusion, AllPixelsOfAVoxelMakeOneUpdateWithTheirMean) {
  VoxelMap map(params(3));
  const Vec3d center(0.375, -0.125, 3.125);
  occupy(map, center);
  ProjectiveFusion fusion;
  const auto& a = fusion.associate(map.occupancy(), feature_camera(), Pose::Identity());
  ASSERT_EQ(a.voxels.size(), 1u);
  ASSERT_GT(a.pixel_count[0], 20u);
  double sx = 0, sy = 0;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x)
      if (a.owner[y * a.width + x] == 0) sx += x, sy += y;
  const double mx = sx / a.pixel_count[0], my = sy / a.pixel_count[0];
  // The footprint is centred on the projected voxel centre.
  EXPECT_NEAR(mx, 150 * center.x() / center.z() + 95.5, 1.0);
  EXPECT_NEAR(my, 150 * center.y() / center.z() + 63.5, 1.0);

  fusion.fuse(map, pixel_coordinate_features(feature_camera()), feature_camera(), Pose::Identity());
  const auto slot = map.semantics().find(map.occupancy().key_of(center));
  ASSERT_TRUE(slot);
  EXPECT_EQ(map.semantics().count_of(*slot), 1u);
  float v[3];
  map.semantics().read(*slot, v);
  EXPECT_NEAR(v[0], mx, 1e-3);
  EXPECT_NEAR(v[1], my, 1e-3);
  EXPECT_FLOAT_EQ(v[2], 1.0f);
}

TEST(ProjectiveFusion, FootprintIsClippedAtTheImageBorderNeverWrapped) {
  VoxelMap map(params(3));
  // Centre projects just right of the image: the visible part must stay at the right edge.
  const double z = 2.0, x = (192.2 - 95.5) * z / 150.0;
  occupy(map, {x, 0.0, z});
  ProjectiveFusion fusion;
  const auto& a = fusion.associate(map.occupancy(), feature_camera(), Pose::Identity());
  ASSERT_EQ(a.voxels.size(), 1u);
  for (int y = 0; y < a.height; ++y)
    for (int px = 0; px < a.width; ++px)
      if (a.owner[y * a.width + px] >= 0) {
        EXPECT_GT(px, 170) << "pixel wrapped to x=" << px;
      }
  // Entirely outside: nothing.
  VoxelMap outside(params(3));
  occupy(outside, {10.0, 0.0, 2.0});
  EXPECT_TRUE(fusion.associate(outside.occupancy(), feature_camera(), Pose::Identity()).voxels.empty());
}

TEST(ProjectiveFusion, DistortedProjectionMatchesOpenCV) {
  CameraModel c = feature_camera();
  c.distortion = {-0.134313, -0.025905, 0.002181, 0.00084, 0.0};
  std::vector<cv::Point3d> obj;
  for (double x = -2; x <= 2; x += 0.5)
    for (double y = -1.5; y <= 1.5; y += 0.5) obj.emplace_back(x, y, 4.0 + x * 0.3);
  std::vector<cv::Point2d> img;
  const cv::Mat K = (cv::Mat_<double>(3, 3) << c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
  const cv::Mat dist = (cv::Mat_<double>(1, 5) << c.distortion[0], c.distortion[1], c.distortion[2],
                        c.distortion[3], c.distortion[4]);
  cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, dist, img);
  for (std::size_t i = 0; i < obj.size(); ++i) {
    const auto uv = c.project({obj[i].x, obj[i].y, obj[i].z});
    ASSERT_TRUE(uv);
    EXPECT_NEAR(uv->x(), img[i].x, 1e-9);
    EXPECT_NEAR(uv->y(), img[i].y, 1e-9);
  }
  EXPECT_FALSE(c.project({0, 0, -1}));
}

TEST(ProjectiveFusion, ScaledIntrinsicsKeepPixelCentresAligned) {
  CameraModel full;
  full.width = 1920, full.height = 1200, full.fx = 2813.643275, full.fy = 2808.326079, full.cx = 969.285772,
  full.cy = 624.049972;
  const CameraModel small = full.scaled(192, 128);
  const Vec3d p(0.7, -0.4, 6.0);
  const auto a = *full.project(p), b = *small.project(p);
  EXPECT_NEAR((a.x() + 0.5) * 192.0 / 1920.0 - 0.5, b.x(), 1e-9);
  EXPECT_NEAR((a.y() + 0.5) * 128.0 / 1200.0 - 0.5, b.y(), 1e-9);
}

TEST(ProjectiveFusion, RejectsMismatchedFeatureMaps) {
  VoxelMap map(params(4));
  ProjectiveFusion fusion;
  EXPECT_THROW(fusion.fuse(map, FeatureMap(3, 128, 192), feature_camera(), Pose::Identity()), Error);  // wrong dim
  EXPECT_THROW(fusion.fuse(map, FeatureMap(4, 64, 96), feature_camera(), Pose::Identity()), Error);    // wrong size
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// Far outside the field of view the plumb_bob polynomial folds back into the image; such voxels
// must not be associated (they would cover the whole image from just beside the camera).
TEST(ProjectiveFusion, DistortionFoldBackIsRejected) {
  CameraModel c = feature_camera();
  c.distortion = {-0.134313, -0.025905, 0.002181, 0.00084, 0.0};
  const Vec3d beside(1.2, 1.2, 0.9);  // 60 degrees off axis
  const Eigen::Vector2d folded = c.distort({beside.x() / beside.z(), beside.y() / beside.z()});
  ASSERT_LT(std::abs(c.fx * folded.x() + c.cx), 192.0) << "the polynomial folds this point into the image";
  EXPECT_FALSE(c.project(beside));
  VoxelMap map(params(3));
  occupy(map, beside);
  ProjectiveFusion fusion;
  EXPECT_TRUE(fusion.associate(map.occupancy(), c, Pose::Identity()).voxels.empty());
}

}  // namespace
}  // namespace slamvdb
