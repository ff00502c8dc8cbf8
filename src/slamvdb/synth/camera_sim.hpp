#pragma once
// A simulated RELLIS-3D-like camera: pinhole + plumb_bob distortion (CameraModel), rendering an
// RGB image (class albedo with world-fixed texture, sun shading, sky gradient) and the matching
// 2D label image by casting one ray through every pixel centre.
#include <opencv2/core.hpp>
#include <vector>

#include "slamvdb/core/simulated_view.hpp"
#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/synth/scene.hpp"

namespace slamvdb::synth {

inline constexpr uint16_t kSkyClass = 7;

// RELLIS-3D's Basler camera (1920 x 1200 intrinsics and distortion) at another resolution.
CameraModel rellis_camera(int width, int height);
// RELLIS-3D's os1_cloud_node -> pylon_camera_node transform: the camera pose in the LiDAR frame
// (camera z forward, x right, y down; it looks along the LiDAR's -x).
Pose rellis_T_lidar_camera();

// Normalised undistorted coordinates (x/z, y/z) whose distortion is `distorted` (Newton's method
// on CameraModel::distort, so projecting the result lands back on the pixel). Throws Error if the
// distortion cannot be inverted there.
Eigen::Vector2d undistort_normalized(const CameraModel& camera, const Eigen::Vector2d& distorted);

// A smooth, roughly standard-normal field over the world (three octaves of value noise with a
// coarsest wavelength of `scale` metres), keyed by `seed`: where the simulated encoder errs
// persistently. Deterministic.
double world_appearance(const Vec3d& p_world, double scale, uint64_t seed);

struct RenderedFrame {
  cv::Mat bgr;     // CV_8UC3, OpenCV channel order
  cv::Mat labels;  // CV_8UC1, RELLIS-3D class ids, kSkyClass where a ray hits nothing
  cv::Mat view;    // CV_16UC3, the view geometry (core/simulated_view.hpp; empty unless asked for)
};

struct RenderOptions {
  bool view_geometry = false;      // also render RenderedFrame::view
  double appearance_scale_m = 4.0; // wavelength of the world appearance field
  uint64_t appearance_seed = 1;
};

class CameraSimulator {
 public:
  // Precomputes the unit ray of every pixel centre in the camera frame.
  explicit CameraSimulator(const CameraModel& camera);

  const CameraModel& camera() const { return camera_; }
  const Vec3d& ray(int u, int v) const { return rays_[static_cast<std::size_t>(v) * camera_.width + u]; }
  RenderedFrame render(const Scene& scene, const Pose& T_world_camera, double max_range,
                       const RenderOptions& options = {}) const;

 private:
  CameraModel camera_;
  std::vector<Vec3d> rays_;  // row-major
};

}  // namespace slamvdb::synth
