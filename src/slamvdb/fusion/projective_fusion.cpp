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

std::string_view to_string(FusionWeighting w) {
  const auto i = static_cast<std::size_t>(w);
  return i < kFusionRuleNames.size() ? kFusionRuleNames[i] : kFusionRuleNames[0];
}

FusionWeighting fusion_weighting_from_string(std::string_view s) {
  for (std::size_t i = 0; i < kFusionRuleNames.size(); ++i)
    if (s == kFusionRuleNames[i]) return static_cast<FusionWeighting>(i);
  throw Error(fmt::format("unknown fusion weighting '{}' (expected paper, quality or single-view)", s));
}

MapInfo map_info_for(std::string source, std::string model_id, std::string features, const FusionParams& fusion) {
  MapInfo info;
  info.model_id = std::move(model_id);
  info.source = std::move(source);
  info.fusion = std::string(to_string(fusion.weighting));
  info.features = std::move(features);
  return info;
}

FusionStats& FusionStats::operator+=(const FusionStats& o) {
  candidates += o.candidates, fused_voxels += o.fused_voxels, occluded += o.occluded;
  pixels_used += o.pixels_used, pixels_total += o.pixels_total, pixels_other_submaps += o.pixels_other_submaps;
  pixels_nonfinite += o.pixels_nonfinite, pixels_zero += o.pixels_zero;
  pixels_near_edges += o.pixels_near_edges, weight_sum += o.weight_sum;
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

void ProjectiveFusion::mark_depth_edges(double voxel_size) {
  const int W = assoc_.width, H = assoc_.height;
  const float min_step = static_cast<float>(3.0 * voxel_size), rel = static_cast<float>(params_.quality_edge_step);
  std::vector<uint8_t>& edge = edge_;
  edge.assign(static_cast<std::size_t>(W) * H, 0);
  // A step between two neighbours marks both; a pixel without a voxel (sky, beyond max_depth) is
  // infinitely far, so the outline of what the map holds is a discontinuity too.
  const auto step = [&](float a, float b) {
    if (!std::isfinite(a) || !std::isfinite(b)) return std::isfinite(a) != std::isfinite(b);
    return std::abs(a - b) > std::max(min_step, rel * std::min(a, b));
  };
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      if (x + 1 < W && step(depth_[i], depth_[i + 1])) edge[i] = edge[i + 1] = 1;
      if (y + 1 < H && step(depth_[i], depth_[i + W])) edge[i] = edge[i + W] = 1;
    }
  // Grow the marks by quality_edge_px - 1 pixels (Chebyshev), a row pass then a column pass.
  const int r = std::max(0, params_.quality_edge_px - 1);
  if (r == 0) return;
  std::vector<uint8_t> grown(edge.size(), 0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (edge[static_cast<std::size_t>(y) * W + x])
        for (int dx = std::max(0, x - r); dx <= std::min(W - 1, x + r); ++dx) grown[static_cast<std::size_t>(y) * W + dx] = 1;
  std::fill(edge.begin(), edge.end(), 0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (grown[static_cast<std::size_t>(y) * W + x])
        for (int dy = std::max(0, y - r); dy <= std::min(H - 1, y + r); ++dy) edge[static_cast<std::size_t>(dy) * W + x] = 1;
}

float ProjectiveFusion::observation_weight(const OccupancyGrid& grid, const VoxelKey& key, const Vec3d& camera_in_grid,
                                           double border_term, bool edge_only) const {
  const Vec3d centre = grid.center_of(key);
  const Vec3d to_camera = camera_in_grid - centre;
  const double d = to_camera.norm();
  if (params_.weighting == FusionWeighting::kSingleView) return static_cast<float>(1.0 / std::max(d, 1e-3));
  const double r = d / params_.quality_range_m;
  double w = 1.0 / (1.0 + r * r);
  // The surface normal: towards the neighbours the LiDAR saw free (the side the surface faces).
  Vec3d normal = Vec3d::Zero();
  static const int kFaces[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (const auto& f : kFaces) {
    const auto lo = grid.log_odds(VoxelKey(key.x() + f[0], key.y() + f[1], key.z() + f[2]));
    if (lo && *lo < grid.params().occupied_threshold) normal += Vec3d(f[0], f[1], f[2]);
  }
  if (normal.squaredNorm() > 0 && d > 0)
    w *= std::max(std::abs(normal.normalized().dot(to_camera / d)), params_.quality_min_incidence_cos);
  w *= border_term;
  if (edge_only) w *= params_.quality_edge_only_weight;
  return static_cast<float>(std::max(w, 1e-6));
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
  const bool single_view = params_.weighting == FusionWeighting::kSingleView;
  if (single_view != submap.semantics().params().single_view)
    throw Error(single_view ? "single-view fusion needs a map made for it (its semantic layer keeps one observation)"
                            : "a single-view map takes only single-view fusion");

  const Association& a = associate(submap.occupancy(), camera, T_submap_camera, occluders, T_world_submap);
  FusionStats stats;
  stats.candidates = a.candidates;
  stats.occluded = a.occluded;
  stats.pixels_total = a.owner.size();
  stats.pixels_other_submaps = a.pixels_other_submaps;
  const bool quality = params_.weighting == FusionWeighting::kQuality;
  const bool weighted = params_.weighting != FusionWeighting::kPaper;

  // Pixels near depth edges carry features of both sides: they are left out of a voxel that has
  // other pixels in this view.
  if (quality) {
    mark_depth_edges(submap.voxel_size());
    inner_count_.assign(a.voxels.size(), 0);
    for (std::size_t p = 0; p < a.owner.size(); ++p)
      if (a.owner[p] >= 0 && !edge_[p]) ++inner_count_[a.owner[p]];
  }

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
  if (quality) border_sum_.assign(a.voxels.size(), 0.0f);
  const int W = a.width, H = a.height;
  const auto border_term = [&](std::size_t p) {
    if (params_.quality_border_px <= 0) return 1.0f;
    const int x = static_cast<int>(p % static_cast<std::size_t>(W)), y = static_cast<int>(p / static_cast<std::size_t>(W));
    const int border = std::min(std::min(x, W - 1 - x), std::min(y, H - 1 - y));
    const double t = std::min(1.0, static_cast<double>(border) / params_.quality_border_px);
    return static_cast<float>(params_.quality_border_weight + (1.0 - params_.quality_border_weight) * t);
  };
  std::size_t on_voxels = 0;
  for (std::size_t p = 0; p < a.owner.size(); ++p) {
    const int32_t o = a.owner[p];
    if (o < 0) continue;
    ++on_voxels;
    if (quality && edge_[p] && inner_count_[o] > 0) {
      ++stats.pixels_near_edges;
      continue;
    }
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
      if (quality) border_sum_[o] += border_term(p);
    }
  }
  const std::size_t invalid = stats.pixels_nonfinite + stats.pixels_zero;
  if (on_voxels > 0 && static_cast<double>(invalid) > params_.max_invalid_fraction * static_cast<double>(on_voxels)) {
    stats.frames_refused_invalid = 1;  // the sums are dropped: nothing of the frame is fused
    stats.pixels_used = 0;
    return stats;
  }
  const Vec3d camera_in_grid = T_submap_camera.translation();
  for (std::size_t v = 0; v < a.voxels.size(); ++v) {
    if (valid_count_[v] == 0) continue;
    float* acc = accum_.data() + v * udim;
    const float inv = 1.0f / static_cast<float>(valid_count_[v]);
    for (int c = 0; c < dim; ++c) acc[c] *= inv;
    if (!weighted) {
      submap.semantics().integrate(a.voxels[v], acc);
      stats.weight_sum += 1.0;
    } else {
      const float w = observation_weight(submap.occupancy(), a.voxels[v], camera_in_grid,
                                         quality ? border_sum_[v] * inv : 1.0, quality && inner_count_[v] == 0);
      if (single_view) submap.semantics().keep_best(a.voxels[v], acc, w);
      else submap.semantics().integrate(a.voxels[v], acc, w);
      stats.weight_sum += w;
    }
    ++stats.fused_voxels;
  }
  return stats;
}

}  // namespace slamvdb
