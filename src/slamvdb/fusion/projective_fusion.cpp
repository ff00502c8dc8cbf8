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

FusionStats& FusionStats::operator+=(const FusionStats& o) {
  candidates += o.candidates, fused_voxels += o.fused_voxels, occluded += o.occluded;
  pixels_used += o.pixels_used, pixels_total += o.pixels_total, pixels_other_submaps += o.pixels_other_submaps;
  pixels_nonfinite += o.pixels_nonfinite, pixels_zero += o.pixels_zero;
  frames_refused_invalid += o.frames_refused_invalid;
  return *this;
}

// Rasterises every occupied voxel of `grid` in the view volume into the depth buffer. Target
// voxels become candidates; voxels of another submap only occlude (owner kOtherSubmap).
void ProjectiveFusion::rasterise(const OccupancyGrid& grid, const CameraModel& camera, const Pose& T_camera_grid,
                                 bool target) {
  const int W = camera.width, H = camera.height;
  const Eigen::Matrix3d R = T_camera_grid.linear();
  const Vec3d t = T_camera_grid.translation();
  const double vs = grid.voxel_size();
  const double block_radius = kBlockSide * vs * std::sqrt(3.0) / 2;
  const double cone = view_cone_half_angle(camera);
  const bool distorted = camera.has_distortion();

  // A voxel covers the pixels its inscribed sphere covers. (The bounding box of its eight projected
  // corners, used before, overhangs the voxel by up to sqrt(3) at oblique views: a ground voxel in
  // front of a trunk took the trunk's pixels. Measured on the default SIMULATED sequence with an
  // ideal encoder, second half: voxel accuracy 94.05% -> 95.10%, hit rate 93.91% -> 95.06%, and
  // 12% more voxels seen at all.)
  const double radius = 0.5 * vs;

  std::vector<int32_t>& owner = assoc_.owner;
  const Vec3d camera_in_grid = T_camera_grid.inverse().translation();
  grid.for_each_block_near(camera_in_grid, params_.max_depth + block_radius,
                           [&](const BlockKey& bk, const OccupancyGrid::Block& block) {
    if (block.num_occupied == 0) return;
    const Vec3d block_center = ((bk.cast<double>() * kBlockSide).array() + kBlockSide / 2.0).matrix() * vs;
    const Vec3d pb = R * block_center + t;
    const double db = pb.norm();
    if (db - block_radius > params_.max_depth || pb.z() + block_radius < params_.min_depth) return;
    if (db > block_radius && std::acos(std::clamp(pb.z() / db, -1.0, 1.0)) > cone + std::asin(block_radius / db))
      return;
    for (int i = 0; i < kBlockVoxels; ++i) {
      if (!block.occupied(i)) continue;
      const VoxelKey key = voxel_of(bk, i);
      const Vec3d p = R * grid.center_of(key) + t;
      const double dist = p.norm();
      if (p.z() < params_.min_depth || dist > params_.max_depth) continue;
      if (p.z() <= radius) continue;  // the voxel reaches the camera's plane
      double uc = camera.fx * p.x() / p.z() + camera.cx, vc = camera.fy * p.y() / p.z() + camera.cy;
      if (distorted) {  // lens distortion moves the footprint; over one voxel it barely reshapes it
        const auto projected = camera.project(p);
        if (!projected) continue;
        uc = projected->x(), vc = projected->y();
      }
      const double hu = camera.fx * radius / p.z(), hv = camera.fy * radius / p.z();
      const double umin = uc - hu, umax = uc + hu, vmin = vc - hv, vmax = vc + hv;
      // Pixels whose centres lie inside the footprint; a footprint smaller than a pixel takes the
      // pixel under the voxel centre.
      int x0 = static_cast<int>(std::ceil(umin)), x1 = static_cast<int>(std::floor(umax));
      int y0 = static_cast<int>(std::ceil(vmin)), y1 = static_cast<int>(std::floor(vmax));
      if (x0 > x1) x0 = x1 = static_cast<int>(std::lround(uc));
      if (y0 > y1) y0 = y1 = static_cast<int>(std::lround(vc));
      x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, W - 1), y1 = std::min(y1, H - 1);
      if (x0 > x1 || y0 > y1) continue;  // entirely outside the image
      // Another submap's voxel on the same surface lies at about the same depth (its grid is
      // offset): it occludes only what is more than a voxel diagonal behind it.
      const float d = static_cast<float>(target ? dist : dist + std::sqrt(3.0) * vs);
      const int32_t id = target ? static_cast<int32_t>(candidate_keys_.size()) : Association::kOtherSubmap;
      for (int y = y0; y <= y1; ++y) {
        float* drow = depth_.data() + static_cast<std::size_t>(y) * W;
        int32_t* orow = owner.data() + static_cast<std::size_t>(y) * W;
        for (int x = x0; x <= x1; ++x)
          if (d < drow[x]) drow[x] = d, orow[x] = id;
      }
      if (target) candidate_keys_.push_back(key);
    }
  });
}

const Association& ProjectiveFusion::associate(const OccupancyGrid& grid, const CameraModel& camera,
                                               const Pose& T_submap_camera, std::span<const PlacedVoxelMap> occluders,
                                               const Pose& T_world_submap) {
  camera.validate();
  const int W = camera.width, H = camera.height;
  Association& a = assoc_;
  a.width = W;
  a.height = H;
  a.voxels.clear();
  a.pixel_count.clear();
  a.pixels_other_submaps = 0;
  a.owner.assign(static_cast<std::size_t>(W) * H, Association::kNone);
  depth_.assign(static_cast<std::size_t>(W) * H, std::numeric_limits<float>::infinity());
  candidate_keys_.clear();

  // Pass 1: rasterise every candidate (and every occluder) into the depth buffer.
  const Pose T_camera_submap = T_submap_camera.inverse();
  rasterise(grid, camera, T_camera_submap, true);
  const Pose T_camera_world = T_camera_submap * T_world_submap.inverse();
  for (const PlacedVoxelMap& o : occluders) rasterise(o.voxels->occupancy(), camera, T_camera_world * o.T_world_submap, false);
  a.candidates = candidate_keys_.size();

  // Pass 2: renumber the candidates that kept pixels; the rest were occluded.
  std::vector<int32_t> compact(candidate_keys_.size(), -1);
  for (int32_t& o : a.owner) {
    if (o < 0) {
      a.pixels_other_submaps += o == Association::kOtherSubmap;
      continue;
    }
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

FusionStats ProjectiveFusion::fuse(VoxelMap& submap, const FeatureMap& features, const CameraModel& camera,
                                   const Pose& T_submap_camera, std::span<const PlacedVoxelMap> occluders,
                                   const Pose& T_world_submap) {
  const int dim = submap.semantics().dim();
  if (features.dim() != dim)
    throw Error(fmt::format("feature map has {} channels but the map stores {}-d embeddings", features.dim(), dim));
  if (features.width() != camera.width || features.height() != camera.height)
    throw Error(fmt::format("feature map is {}x{} but the camera model is {}x{}", features.width(), features.height(),
                            camera.width, camera.height));

  const Association& a = associate(submap.occupancy(), camera, T_submap_camera, occluders, T_world_submap);
  FusionStats stats;
  stats.candidates = a.candidates;
  stats.occluded = a.occluded;
  stats.pixels_total = a.owner.size();
  stats.pixels_other_submaps = a.pixels_other_submaps;

  // A pixel whose feature vector is not finite (a network's fp16 overflow, a damaged file) or
  // all zero carries no observation: it is skipped and counted, so that one bad frame can never
  // turn a voxel's running mean into NaN for good.
  //
  // One pass over the feature map (its 25-50 MB are what bounds fusion): each pixel is checked and
  // summed while its vector is in L1. fp16 features are widened in registers (F16C where the CPU
  // has it): read in half the bytes, and summed exactly as their fp32 values would be.
  const auto udim = static_cast<std::size_t>(dim);
  accum_.assign(a.voxels.size() * udim, 0.0f);
  valid_count_.assign(a.voxels.size(), 0);
  std::size_t on_voxels = 0;
  for (std::size_t p = 0; p < a.owner.size(); ++p) {
    const int32_t o = a.owner[p];
    if (o < 0) continue;
    ++on_voxels;
    const EmbeddingView f = features.view(p);
    const float n2 = kernels::squared_norm_4way(f, udim);
    if (!std::isfinite(n2)) {
      ++stats.pixels_nonfinite;
    } else if (n2 == 0.0f) {
      ++stats.pixels_zero;
    } else {
      kernels::add(accum_.data() + static_cast<std::size_t>(o) * udim, f, udim);
      ++valid_count_[o];
      ++stats.pixels_used;
    }
  }
  const std::size_t invalid = stats.pixels_nonfinite + stats.pixels_zero;
  if (on_voxels > 0 && static_cast<double>(invalid) > params_.max_invalid_fraction * static_cast<double>(on_voxels)) {
    stats.frames_refused_invalid = 1;  // the sums are dropped: nothing of the frame is fused
    stats.pixels_used = 0;
    return stats;
  }
  for (std::size_t v = 0; v < a.voxels.size(); ++v) {
    if (valid_count_[v] == 0) continue;
    float* acc = accum_.data() + v * udim;
    const float inv = 1.0f / static_cast<float>(valid_count_[v]);
    for (int c = 0; c < dim; ++c) acc[c] *= inv;
    submap.semantics().integrate(a.voxels[v], acc);
    ++stats.fused_voxels;
  }
  return stats;
}

}  // namespace slamvdb
