#include "slamvdb/sessions/surface_refinement.hpp"

#include <absl/container/flat_hash_set.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "slamvdb/core/se3.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"

namespace slamvdb::sessions {

using localization::LocalVoxel;
using localization::pack_voxel;
using localization::voxel_of;

namespace {

// The squared distance from coordinate p (in cell k) to the nearest face of cell k + d along one
// axis, less a margin (a millionth of a cell) for floor()'s rounding of points on a cell's face:
// no point of that cell is nearer along this axis. 0 for the point's own cell.
double surface_cell_gap(double p, int k, int d, double cell) {
  if (d == 0) return 0.0;
  const double gap = (d > 0 ? (k + d) * cell - p : p - (k + d + 1) * cell) - 1e-6 * cell;
  return gap > 0.0 ? gap * gap : 0.0;
}

}  // namespace

template <typename F>
void SurfacePlanes::for_each_near(const Vec3d& p, int reach, F&& f) const {
  const LocalVoxel k = voxel_of(p, cell_);
  for (int dx = -reach; dx <= reach; ++dx)
    for (int dy = -reach; dy <= reach; ++dy)
      for (int dz = -reach; dz <= reach; ++dz) {
        const auto it = cells_.find(pack_voxel(k + LocalVoxel(dx, dy, dz)));
        if (it == cells_.end()) continue;
        for (const std::size_t i : it->second) f(i);
      }
}

namespace {

// Marks the base points within `near_distance` of one of `near` (per axis), and some a little
// farther: those whose cell of near_distance + voxel is next to one holding a near point (two
// points that close are at most one such cell apart along each axis). 27 look-ups a point where
// the exact test of every voxel cell within reach took 125 per near point.
std::vector<char> points_near(const std::vector<Vec3d>& points, const std::vector<Vec3d>& near, double cell) {
  absl::flat_hash_set<uint64_t> near_cells;
  near_cells.reserve(near.size() / 4);
  for (const Vec3d& p : near) near_cells.insert(pack_voxel(voxel_of(p, cell)));
  std::vector<char> wanted(points.size(), 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 4096), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const LocalVoxel k = voxel_of(points[i], cell);
      for (int d = 0; d < 27 && !wanted[i]; ++d)
        wanted[i] = near_cells.contains(pack_voxel(k + LocalVoxel(d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1)));
    }
  });
  return wanted;
}

}  // namespace

SurfacePlanes::SurfacePlanes(const std::vector<Vec3d>& base_points, const std::vector<Vec3d>& near,
                             const SurfaceRefinementConfig& config, double near_distance)
    : cell_(config.voxel), points_(base_points) {
  for (std::size_t i = 0; i < points_.size(); ++i) cells_[pack_voxel(voxel_of(points_[i], cell_))].push_back(i);
  centroids_.resize(points_.size());
  normals_.assign(points_.size(), Vec3d::Zero());
  const std::vector<char> wanted = points_near(points_, near, near_distance + cell_);
  // Each point's plane from its neighbours alone: in parallel, the same in any order.
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_.size(), 1024),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t i = range.begin(); i != range.end(); ++i)
                        if (wanted[i]) fit_plane(i, config);
                    });
  planes_ = static_cast<std::size_t>(
      std::count_if(normals_.begin(), normals_.end(), [](const Vec3d& n) { return !n.isZero(); }));
}

void SurfacePlanes::fit_plane(std::size_t i, const SurfaceRefinementConfig& config) {
  const int reach = static_cast<int>(std::ceil(config.normal_radius / cell_));
  const double r2 = config.normal_radius * config.normal_radius;
  Vec3d sum = Vec3d::Zero();
  Eigen::Matrix3d outer = Eigen::Matrix3d::Zero();
  std::size_t n = 0;
  // The cells of the (2 reach + 1)^3 block in for_each_near's order, without those whose box lies
  // beyond the radius (most of the block's corners): their points would all be rejected below,
  // so the sums, and their order, are the same as over the whole block.
  const Vec3d& p = points_[i];
  const LocalVoxel k = voxel_of(p, cell_);
  for (int dx = -reach; dx <= reach; ++dx) {
    const double gx = surface_cell_gap(p.x(), k.x(), dx, cell_);
    for (int dy = -reach; dy <= reach; ++dy) {
      const double gxy = gx + surface_cell_gap(p.y(), k.y(), dy, cell_);
      if (gxy > r2) continue;
      for (int dz = -reach; dz <= reach; ++dz) {
        if (gxy + surface_cell_gap(p.z(), k.z(), dz, cell_) > r2) continue;
        const auto it = cells_.find(pack_voxel(k + LocalVoxel(dx, dy, dz)));
        if (it == cells_.end()) continue;
        for (const std::size_t j : it->second) {
          const Vec3d d = points_[j] - p;  // about the point, for precision far from the origin
          if (d.squaredNorm() > r2) continue;
          sum += d;
          outer += d * d.transpose();
          ++n;
        }
      }
    }
  }
  if (n < config.min_neighbours) return;
  const Vec3d mean = sum / static_cast<double>(n);
  const Eigen::Matrix3d covariance = outer / static_cast<double>(n) - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);  // ascending eigenvalues
  // A plane only where the neighbourhood is flat more than linear (a pole's column of voxels
  // or a lone row has no normal).
  if (solver.eigenvalues()(1) < 0.25 * solver.eigenvalues()(2)) return;
  centroids_[i] = points_[i] + mean;
  normals_[i] = solver.eigenvectors().col(0);
}

bool SurfacePlanes::nearest(const Vec3d& p, Vec3d& centroid, Vec3d& normal) const {
  double best = INFINITY;
  std::size_t found = points_.size();
  for_each_near(p, 1, [&](std::size_t j) {
    const double d2 = (points_[j] - p).squaredNorm();
    if (d2 < best || (d2 == best && j < found)) best = d2, found = j;
  });
  if (found == points_.size() || normals_[found].isZero()) return false;
  centroid = centroids_[found];
  normal = normals_[found];
  return true;
}

namespace {

using SurfaceMatrix6d = Eigen::Matrix<double, 6, 6>;
using SurfaceVector6d = Eigen::Matrix<double, 6, 1>;

struct SurfaceNormalEquations {
  SurfaceMatrix6d JTJ = SurfaceMatrix6d::Zero();
  SurfaceVector6d JTr = SurfaceVector6d::Zero();
  std::size_t count = 0;
};

}  // namespace

SurfaceRefinement refine_on_surface(const std::vector<Vec3d>& other_points, const SurfacePlanes& base,
                                    const Pose& start, const SurfaceRefinementConfig& config) {
  SurfaceRefinement result;
  result.T_base_other = start;
  // Linearised about a point near the data, so that the rotation part is well conditioned.
  Vec3d origin = Vec3d::Zero();
  for (const Vec3d& p : other_points) origin += start * p;
  if (!other_points.empty()) origin /= static_cast<double>(other_points.size());
  for (int it = 0; it < config.max_iterations; ++it) {
    const Pose& T = result.T_base_other;
    const SurfaceNormalEquations eq = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<std::size_t>(0, other_points.size(), 1024), SurfaceNormalEquations{},
        [&](const tbb::blocked_range<std::size_t>& range, SurfaceNormalEquations acc) {
          for (std::size_t i = range.begin(); i != range.end(); ++i) {
            const Vec3d p = T * other_points[i];
            Vec3d c, n;
            if (!base.nearest(p, c, n)) continue;
            const double r = n.dot(p - c);
            if (std::abs(r) > config.max_distance) continue;
            // Left perturbation about `origin`: d(p) = rho + phi x (p - origin).
            SurfaceVector6d J;
            J.head<3>() = n;
            J.tail<3>() = (p - origin).cross(n);
            acc.JTJ.noalias() += J * J.transpose();
            acc.JTr.noalias() += J * r;
            ++acc.count;
          }
          return acc;
        },
        [](const SurfaceNormalEquations& a, const SurfaceNormalEquations& b) {
          return SurfaceNormalEquations{a.JTJ + b.JTJ, a.JTr + b.JTr, a.count + b.count};
        });
    result.iterations = it + 1;
    result.correspondences = eq.count;
    if (eq.count < config.min_correspondences) return result;
    const SurfaceVector6d dx = eq.JTJ.ldlt().solve(-eq.JTr);
    if (!dx.allFinite()) return result;
    // exp(dx) about `origin`: translate to it, apply, translate back.
    Pose to_origin = Pose::Identity(), from_origin = Pose::Identity();
    to_origin.translation() = -origin;
    from_origin.translation() = origin;
    result.T_base_other = from_origin * se3_exp(dx) * to_origin * result.T_base_other;
    if (dx.norm() < config.convergence) break;
  }
  result.ok = true;
  return result;
}

}  // namespace slamvdb::sessions
