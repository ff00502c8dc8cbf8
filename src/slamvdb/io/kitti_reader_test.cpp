#include "slamvdb/io/kitti_reader.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <iomanip>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

using testing::TempDir;

// Calibration of KITTI odometry sequence 00 (P2 has a non-zero third row offset, which a
// t_x-only reading of the baseline would get wrong).
constexpr const char* kCalib =
    "P0: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 0.000000000000e+00 0.000000000000e+00 "
    "7.188560000000e+02 1.852157000000e+02 0.000000000000e+00 0.000000000000e+00 0.000000000000e+00 "
    "1.000000000000e+00 0.000000000000e+00\n"
    "P2: 7.188560000000e+02 0.000000000000e+00 6.071928000000e+02 4.538225000000e+01 0.000000000000e+00 "
    "7.188560000000e+02 1.852157000000e+02 -1.130887000000e-01 0.000000000000e+00 0.000000000000e+00 "
    "1.000000000000e+00 3.779761000000e-03\n"
    "Tr: 4.276802385584e-04 -9.999672484946e-01 -8.084491683471e-03 -1.198459927713e-02 -7.210626507497e-03 "
    "8.081198471645e-03 -9.999413164504e-01 -5.403984729748e-02 9.999738645903e-01 4.859485810390e-04 "
    "-7.206933692422e-03 -2.921968648686e-01\n";

Pose yawed_pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitY()).toRotationMatrix();
  T.translation() = t;
  return T;
}

void write_kitti(const fs::path& dir, int frames, int pose_count) {
  fs::create_directories(dir / "velodyne");
  fs::create_directories(dir / "image_2");
  fs::create_directories(dir / "labels");
  std::ofstream(dir / "calib.txt") << kCalib;
  std::ofstream times(dir / "times.txt"), poses(dir / "poses.txt");
  poses << std::setprecision(17);
  for (int i = 0; i < frames; ++i) {
    char stem[16];
    std::snprintf(stem, sizeof(stem), "%06d", i);
    const float xyzi[4] = {10, 1, -1, 0.3f};
    std::ofstream(dir / "velodyne" / (std::string(stem) + ".bin"), std::ios::binary)
        .write(reinterpret_cast<const char*>(xyzi), sizeof(xyzi));
    cv::imwrite((dir / "image_2" / (std::string(stem) + ".png")).string(),
                cv::Mat(37, 124, CV_8UC3, cv::Scalar(0, 0, 0)));
    times << 0.1 * i << "\n";
  }
  const uint32_t label = 40;
  std::ofstream(dir / "labels" / "000000.label", std::ios::binary).write(reinterpret_cast<const char*>(&label), 4);
  for (int i = 0; i < pose_count; ++i) {
    const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> m =
        yawed_pose(0.1 * i, Vec3d(0.5 * i, 0.01 * i, 1.0 * i)).matrix().topRows<3>();
    for (int k = 0; k < 12; ++k) poses << m.data()[k] << (k == 11 ? "\n" : " ");
  }
}

TEST(KittiReader, ReadsCalibrationPosesAndStamps) {
  TempDir tmp;
  write_kitti(tmp.path, 3, 3);
  const Sequence seq = read_sequence(tmp.path);
  EXPECT_EQ(seq.layout, "kitti");
  EXPECT_DOUBLE_EQ(seq.camera.fx, 718.856);
  EXPECT_DOUBLE_EQ(seq.camera.fy, 718.856);
  EXPECT_DOUBLE_EQ(seq.camera.cx, 607.1928);
  EXPECT_DOUBLE_EQ(seq.camera.cy, 185.2157);
  EXPECT_EQ(seq.camera.width, 124);
  EXPECT_EQ(seq.camera.height, 37);
  EXPECT_FALSE(seq.camera.has_distortion());

  ASSERT_EQ(seq.scans.size(), 3u);
  ASSERT_EQ(seq.images.size(), 3u);
  EXPECT_DOUBLE_EQ(seq.scans[2].stamp, 0.2);
  EXPECT_DOUBLE_EQ(seq.images[2].stamp, 0.2);
  EXPECT_EQ(seq.scans[0].labels.filename(), "000000.label");
  EXPECT_TRUE(seq.scans[1].labels.empty());

  const KittiCalib calib = read_kitti_calib(tmp.path / "calib.txt");
  ASSERT_EQ(seq.poses.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const Pose T_world_cam0 = yawed_pose(0.1 * i, Vec3d(0.5 * i, 0.01 * i, 1.0 * i));
    EXPECT_TRUE(seq.poses.poses()[i].isApprox(T_world_cam0 * calib.T_cam0_velo, 1e-9)) << i;
  }
  // The LiDAR origin sits about 0.27 m behind camera 0 (KITTI's Tr).
  EXPECT_NEAR((seq.poses.poses()[0].translation() - Vec3d(-0.0120, -0.0540, -0.2922)).norm(), 0.0, 1e-3);
}

TEST(KittiReader, CameraModelProjectsLikeP2TimesTr) {
  const fs::path calib_file = fs::temp_directory_path() / ("slamvdb-kitti-calib-" + std::to_string(getpid()) + ".txt");
  std::ofstream(calib_file) << kCalib;
  const KittiCalib calib = read_kitti_calib(calib_file);
  fs::remove(calib_file);
  const CameraModel camera = kitti_camera(calib, 1241, 376);
  const Pose T_camera_lidar = kitti_T_lidar_camera(calib).inverse();
  for (const Vec3d& p_lidar : {Vec3d(10, 1, -1), Vec3d(4, -3, 0.5), Vec3d(30, 8, 2)}) {
    const Eigen::Vector3d h = calib.P2 * (calib.T_cam0_velo * p_lidar).homogeneous();
    const auto uv = camera.project(T_camera_lidar * p_lidar);
    ASSERT_TRUE(uv);
    EXPECT_NEAR(uv->x(), h.x() / h.z(), 1e-9);
    EXPECT_NEAR(uv->y(), h.y() / h.z(), 1e-9);
  }
  // Camera 2 is 6 cm left of camera 0: its origin is at x = -0.06 in camera-0 coordinates.
  const Vec3d cam2_in_cam0 = calib.T_cam0_velo * kitti_T_lidar_camera(calib).translation();
  EXPECT_NEAR(cam2_in_cam0.x(), -0.0599, 1e-3);
}

TEST(KittiReader, RejectsMismatchedCounts) {
  TempDir tmp;
  write_kitti(tmp.path, 3, 2);
  try {
    read_kitti_sequence(tmp.path);
    FAIL() << "2 poses for 3 scans were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("has 2 poses but"), std::string::npos) << e.what();
  }
  std::ofstream(tmp.path / "times.txt") << "0\n0.1\n";
  EXPECT_THROW(read_kitti_sequence(tmp.path), Error);
  fs::remove(tmp.path / "calib.txt");
  std::ofstream(tmp.path / "times.txt") << "0\n0.1\n0.2\n";
  try {
    read_kitti_sequence(tmp.path);
    FAIL() << "a missing calib.txt was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("calib.txt"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace slamvdb
