#include "slamvdb/fusion/projective_fusion.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace {

// Half-angle of a cone around the optical axis that contains the whole image (pinhole bound
// widened by 10% to cover lens distortion); used to cull blocks cheaply.
double view_cone_half_angle(const CameraModel& c) {
  const double dx = std::max(c.cx + 0.5, c.width - 0.5 - c.cx) / c.fx;
  const double dy = std::max(c.cy + 0.5, c.height - 0.5 - c.cy) / c.fy;
  return std::min(std::atan(std::hypot(dx, dy)) * 1.1, M_PI / 2);
}

}  // namespace

const Association& ProjectiveFusion::associate(const OccupancyGrid& grid, const CameraModel& camera,
                                               const Pose& T_map_camera) {
  camera.validate();
  const int W = camera.width, H = camera.height;
  Association& a = assoc_;
  a.width = W;
  a.height = H;
  a.voxels.clear();
  a.pixel_count.clear();
  a.owner.assign(static_cast<std::size_t>(W) * H, -1);
  depth_.assign(static_cast<std::size_t>(W) * H, std::numeric_limits<float>::infinity());
  candidate_keys_.clear();

  const Pose T_camera_map = T_map_camera.inverse();
  const Eigen::Matrix3d R = T_camera_map.linear();
  const Vec3d t = T_camera_map.translation();
  const double vs = grid.voxel_size();
  const double block_radius = OccupancyGrid::kBlockSide * vs * std::sqrt(3.0) / 2;
  const double cone = view_cone_half_angle(camera);
  const bool distorted = camera.has_distortion();

  // The eight corner offsets of a voxel, in the camera frame (same for every voxel of this view).
  std::array<Vec3d, 8> corner;
  for (int k = 0; k < 8; ++k)
    corner[k] = R * Vec3d((k & 1 ? 0.5 : -0.5) * vs, (k & 2 ? 0.5 : -0.5) * vs, (k & 4 ? 0.5 : -0.5) * vs);

  // Pass 1: rasterise every candidate into the depth buffer.
  std::vector<int32_t>& owner = a.owner;
  int32_t candidate = 0;
  grid.for_each_block_near(T_map_camera.translation(), params_.max_depth + block_radius,
                           [&](const VoxelKey& bk, const OccupancyGrid::Block& block) {
    if (block.num_occupied == 0) return;
    const Vec3d block_center = ((bk.cast<double>() * OccupancyGrid::kBlockSide).array() +
                                OccupancyGrid::kBlockSide / 2.0).matrix() * vs;
    const Vec3d pb = R * block_center + t;
    const double db = pb.norm();
    if (db - block_radius > params_.max_depth || pb.z() + block_radius < params_.min_depth) return;
    if (db > block_radius && std::acos(std::clamp(pb.z() / db, -1.0, 1.0)) > cone + std::asin(block_radius / db))
      return;
    for (int i = 0; i < OccupancyGrid::kBlockVoxels; ++i) {
      if (!block.occupied(i)) continue;
      const VoxelKey key = OccupancyGrid::voxel_key(bk, i);
      const Vec3d p = R * grid.center_of(key) + t;
      const double dist = p.norm();
      if (p.z() < params_.min_depth || dist > params_.max_depth) continue;
      double umin = std::numeric_limits<double>::infinity(), umax = -umin, vmin = umin, vmax = -umin;
      bool behind = false;
      for (const Vec3d& o : corner) {
        const Vec3d q = p + o;
        if (q.z() <= 1e-3) {
          behind = true;
          break;
        }
        const double u = camera.fx * q.x() / q.z() + camera.cx, v = camera.fy * q.y() / q.z() + camera.cy;
        umin = std::min(umin, u), umax = std::max(umax, u), vmin = std::min(vmin, v), vmax = std::max(vmax, v);
      }
      if (behind) continue;
      double uc = camera.fx * p.x() / p.z() + camera.cx, vc = camera.fy * p.y() / p.z() + camera.cy;
      if (distorted) {  // lens distortion moves the footprint; over one voxel it barely reshapes it
        const auto projected = camera.project(p);
        if (!projected) continue;
        const Eigen::Vector2d d = *projected;
        umin += d.x() - uc, umax += d.x() - uc, vmin += d.y() - vc, vmax += d.y() - vc;
        uc = d.x(), vc = d.y();
      }
      // Pixels whose centres lie inside the footprint; a footprint smaller than a pixel takes the
      // pixel under the voxel centre.
      int x0 = static_cast<int>(std::ceil(umin)), x1 = static_cast<int>(std::floor(umax));
      int y0 = static_cast<int>(std::ceil(vmin)), y1 = static_cast<int>(std::floor(vmax));
      if (x0 > x1) x0 = x1 = static_cast<int>(std::lround(uc));
      if (y0 > y1) y0 = y1 = static_cast<int>(std::lround(vc));
      x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, W - 1), y1 = std::min(y1, H - 1);
      if (x0 > x1 || y0 > y1) continue;  // entirely outside the image
      const float d = static_cast<float>(dist);
      for (int y = y0; y <= y1; ++y) {
        float* drow = depth_.data() + static_cast<std::size_t>(y) * W;
        int32_t* orow = owner.data() + static_cast<std::size_t>(y) * W;
        for (int x = x0; x <= x1; ++x)
          if (d < drow[x]) drow[x] = d, orow[x] = candidate;
      }
      candidate_keys_.push_back(key);
      ++candidate;
    }
  });
  a.candidates = candidate_keys_.size();

  // Pass 2: renumber the candidates that kept pixels; the rest were occluded.
  std::vector<int32_t> compact(candidate_keys_.size(), -1);
  for (int32_t& o : owner) {
    if (o < 0) continue;
    int32_t& c = compact[o];
    if (c < 0) {
      c = static_cast<int32_t>(a.voxels.size());
      a.voxels.push_back(candidate_keys_[o]);
      a.pixel_count.push_back(0);
    }
    ++a.pixel_count[c];
    o = c;
  }
  a.occluded = a.candidates - a.voxels.size();
  return a;
}

FusionStats ProjectiveFusion::fuse(VoxelMap& map, const FeatureMap& features, const CameraModel& camera,
                                   const Pose& T_map_camera) {
  const int dim = map.semantics().dim();
  if (features.dim != dim)
    throw Error(fmt::format("feature map has {} channels but the map stores {}-d embeddings", features.dim, dim));
  if (features.width != camera.width || features.height != camera.height)
    throw Error(fmt::format("feature map is {}x{} but the camera model is {}x{}", features.width, features.height,
                            camera.width, camera.height));
  if (features.data.size() != static_cast<std::size_t>(dim) * features.width * features.height)
    throw Error("feature map data size does not match its shape");

  const Association& a = associate(map.occupancy(), camera, T_map_camera);
  FusionStats stats;
  stats.candidates = a.candidates;
  stats.occluded = a.occluded;
  stats.fused_voxels = a.voxels.size();
  stats.pixels_total = a.owner.size();

  accum_.assign(a.voxels.size() * dim, 0.0f);
  const float* f = features.data.data();
  for (std::size_t p = 0; p < a.owner.size(); ++p, f += dim) {
    const int32_t o = a.owner[p];
    if (o < 0) continue;
    float* acc = accum_.data() + static_cast<std::size_t>(o) * dim;
    for (int c = 0; c < dim; ++c) acc[c] += f[c];
    ++stats.pixels_used;
  }
  for (std::size_t v = 0; v < a.voxels.size(); ++v) {
    float* acc = accum_.data() + v * dim;
    const float inv = 1.0f / static_cast<float>(a.pixel_count[v]);
    for (int c = 0; c < dim; ++c) acc[c] *= inv;
    map.semantics().integrate(a.voxels[v], acc);
  }
  return stats;
}

}  // namespace slamvdb
