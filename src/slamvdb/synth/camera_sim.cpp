#include "slamvdb/synth/camera_sim.hpp"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/synth/random.hpp"

namespace slamvdb::synth {

namespace {

// Smooth 3D value noise in [0, 1] (trilinear over hashed lattice values with smoothstep weights).
double value_noise(const Vec3d& p) {
  const Vec3d f = p.array().floor();
  const auto ix = static_cast<int64_t>(f.x()), iy = static_cast<int64_t>(f.y()), iz = static_cast<int64_t>(f.z());
  Vec3d w = p - f;
  w = w.cwiseProduct(w).cwiseProduct(Vec3d::Constant(3.0) - 2.0 * w);
  double c[2][2][2];
  for (int dz = 0; dz < 2; ++dz)
    for (int dy = 0; dy < 2; ++dy)
      for (int dx = 0; dx < 2; ++dx) c[dz][dy][dx] = lattice_hash(ix + dx, iy + dy, iz + dz);
  const auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
  const double y0 = lerp(lerp(c[0][0][0], c[0][0][1], w.x()), lerp(c[0][1][0], c[0][1][1], w.x()), w.y());
  const double y1 = lerp(lerp(c[1][0][0], c[1][0][1], w.x()), lerp(c[1][1][0], c[1][1][1], w.x()), w.y());
  return lerp(y0, y1, w.z());
}

const Vec3d kSun = Vec3d(0.45, 0.35, 0.82).normalized();
const Eigen::Vector3f kHorizon(0.80f, 0.85f, 0.92f), kZenith(0.30f, 0.48f, 0.80f);

Eigen::Vector3f sky_colour(const Vec3d& dir) {
  const float up = static_cast<float>(std::sqrt(std::clamp(dir.z(), 0.0, 1.0)));
  return kHorizon + (kZenith - kHorizon) * up;
}

Eigen::Vector3f surface_colour(const SceneHit& hit, const Vec3d& point) {
  const double grain = lattice_hash(static_cast<int64_t>(std::floor(point.x() * 25.0)),
                                    static_cast<int64_t>(std::floor(point.y() * 25.0)),
                                    static_cast<int64_t>(std::floor(point.z() * 25.0)));
  const double blotch = value_noise(point * 1.4);
  const double texture = 1.0 + 0.16 * (grain - 0.5) + 0.3 * (blotch - 0.5);
  const double shade = 0.4 + 0.6 * std::max(0.0, hit.normal.dot(kSun));
  const float haze = static_cast<float>(1.0 - std::exp(-hit.range / 400.0));
  const Eigen::Vector3f lit = hit.albedo * static_cast<float>(texture * shade);
  return lit + (kHorizon - lit) * haze;
}

}  // namespace

double world_appearance(const Vec3d& p_world, double scale, uint64_t seed) {
  // Value noise has mean 0.5 and (per octave) a standard deviation of about 0.155 (measured over
  // 10^6 points); three octaves of halving amplitude are summed and scaled to unit variance.
  const Vec3d offset(static_cast<double>(seed % 1000003) * 0.618, static_cast<double>(seed % 999983) * 0.382, 17.0);
  double sum = 0, amplitude = 1, norm = 0;
  Vec3d p = p_world / scale + offset;
  for (int octave = 0; octave < 3; ++octave) {
    sum += amplitude * (value_noise(p) - 0.5);
    norm += amplitude * amplitude;
    amplitude *= 0.5;
    p = 2.03 * p + Vec3d(5.1, 9.7, 3.3);
  }
  return sum / (0.155 * std::sqrt(norm));
}

CameraModel rellis_camera(int width, int height) {
  CameraModel full;
  full.width = 1920;
  full.height = 1200;
  full.fx = 2813.643275;
  full.fy = 2808.326079;
  full.cx = 969.285772;
  full.cy = 624.049972;
  full.distortion = {-0.134313, -0.025905, 0.002181, 0.00084, 0.0};
  return full.scaled(width, height);
}

Pose rellis_T_lidar_camera() {
  Pose T = Pose::Identity();
  T.linear() = Eigen::Quaterniond(-0.50507811, 0.51206185, 0.49024953, -0.49228464).normalized().toRotationMatrix();
  T.translation() = Vec3d(-0.13165462, 0.03870398, -0.17253834);
  return T;
}

Eigen::Vector2d undistort_normalized(const CameraModel& camera, const Eigen::Vector2d& distorted) {
  const auto& [k1, k2, p1, p2, k3] = camera.distortion;
  Eigen::Vector2d xy = distorted;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d residual = camera.distort(xy) - distorted;
    if (residual.norm() < 1e-13) return xy;
    const double x = xy.x(), y = xy.y(), r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dradial_dr2 = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
    Eigen::Matrix2d J;
    J << radial + 2.0 * x * x * dradial_dr2 + 2.0 * p1 * y + 6.0 * p2 * x,
        2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y,
        2.0 * x * y * dradial_dr2 + 2.0 * p1 * x + 2.0 * p2 * y,
        radial + 2.0 * y * y * dradial_dr2 + 6.0 * p1 * y + 2.0 * p2 * x;
    if (!(J.determinant() > 1e-6)) break;  // past the fold where the lens model stops being invertible
    xy -= J.inverse() * residual;
  }
  if ((camera.distort(xy) - distorted).norm() < 1e-10) return xy;
  throw Error(
      fmt::format("camera distortion {} {} {} {} {} cannot be inverted at normalised point ({:.4f}, {:.4f}); "
                  "the image corners lie beyond the lens model's valid field",
                  k1, k2, p1, p2, k3, distorted.x(), distorted.y()));
}

CameraSimulator::CameraSimulator(const CameraModel& camera) : camera_(camera) {
  camera_.validate();
  rays_.resize(static_cast<std::size_t>(camera_.width) * camera_.height);
  for (int v = 0; v < camera_.height; ++v)
    for (int u = 0; u < camera_.width; ++u) {
      const Eigen::Vector2d d((u - camera_.cx) / camera_.fx, (v - camera_.cy) / camera_.fy);
      const Eigen::Vector2d xy = undistort_normalized(camera_, d);
      rays_[static_cast<std::size_t>(v) * camera_.width + u] = Vec3d(xy.x(), xy.y(), 1.0).normalized();
    }
}

RenderedFrame CameraSimulator::render(const Scene& scene, const Pose& T_world_camera, double max_range,
                                      const RenderOptions& options) const {
  RenderedFrame frame{cv::Mat(camera_.height, camera_.width, CV_8UC3), cv::Mat(camera_.height, camera_.width, CV_8UC1),
                      options.view_geometry ? cv::Mat(camera_.height, camera_.width, CV_16UC3) : cv::Mat()};
  const Vec3d origin = T_world_camera.translation();
  const Eigen::Matrix3d R = T_world_camera.linear();
  tbb::parallel_for(tbb::blocked_range<int>(0, camera_.height), [&](const tbb::blocked_range<int>& rows) {
    for (int v = rows.begin(); v < rows.end(); ++v) {
      auto* bgr = frame.bgr.ptr<cv::Vec3b>(v);
      auto* label = frame.labels.ptr<uint8_t>(v);
      for (int u = 0; u < camera_.width; ++u) {
        const Vec3d dir = R * ray(u, v);
        const auto hit = scene.raycast(origin, dir, max_range);
        const Eigen::Vector3f c = hit ? surface_colour(*hit, origin + hit->range * dir) : sky_colour(dir);
        label[u] = static_cast<uint8_t>(hit ? hit->label : kSkyClass);
        for (int k = 0; k < 3; ++k)
          bgr[u][2 - k] = static_cast<uint8_t>(std::clamp(std::lround(255.0f * c[k]), 0L, 255L));
        if (options.view_geometry) {
          auto& g = frame.view.ptr<cv::Vec<uint16_t, 3>>(v)[u];
          if (!hit) {
            g = {0, 0, 32768};
            continue;
          }
          const Vec3d p = origin + hit->range * dir;
          const double a = world_appearance(p, options.appearance_scale_m, options.appearance_seed);
          g[0] = static_cast<uint16_t>(std::clamp(std::lround(hit->range / kViewRangeUnit), 1L, 65535L));
          g[1] = static_cast<uint16_t>(std::clamp(std::lround(65535.0 * std::abs(hit->normal.dot(dir))), 0L, 65535L));
          g[2] = static_cast<uint16_t>(std::clamp(std::lround(32768.0 + kViewAppearanceScale * a), 0L, 65535L));
        }
      }
    }
  });
  return frame;
}

}  // namespace slamvdb::synth
