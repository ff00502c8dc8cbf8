#include "slamvdb/localization/registration.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <span>

#include "slamvdb/core/se3.hpp"
#include "slamvdb/localization/preprocessing.hpp"

namespace slamvdb::localization {

namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

struct NormalEquations {
  Matrix6d JTJ = Matrix6d::Zero();
  Vector6d JTr = Vector6d::Zero();
  std::size_t count = 0;
  NormalEquations operator+(const NormalEquations& o) const { return {JTJ + o.JTJ, JTr + o.JTr, count + o.count}; }
};

// The grain size fixes how the points are split, so the sums (and the result) are the same on
// every run and thread count.
constexpr std::size_t kGrain = 1024;

NormalEquations build_system(const std::vector<Vec3d>& source, const VoxelHashMap& target, const Pose& T,
                             double max_distance, double kernel_scale) {
  const double max2 = max_distance * max_distance;
  const double kappa = kernel_scale;
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, source.size(), kGrain), NormalEquations{},
      [&](const tbb::blocked_range<std::size_t>& range, NormalEquations acc) {
        Eigen::Matrix<double, 3, 6> J;
        J.leftCols<3>().setIdentity();
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          const Vec3d p = T * source[i];
          Vec3d q;
          double d2;
          if (!target.nearest(p, q, d2) || d2 > max2) continue;
          const Vec3d r = p - q;
          // Left perturbation exp(dx) * T: d(p)/d(rho, phi) = [I | -hat(p)].
          J.rightCols<3>() << 0.0, p.z(), -p.y(), -p.z(), 0.0, p.x(), p.y(), -p.x(), 0.0;
          // Geman-McClure as in the KISS-ICP paper, rho(e) = (e^2 / 2) / (kappa + e^2), whose IRLS
          // weight is kappa^2 / (kappa + e^2)^2.
          const double w = kappa * kappa / ((kappa + d2) * (kappa + d2));
          // acc += w J^T J and w J^T r, written out: Eigen's lazy 6x3 * 3x6 product made a call per
          // coefficient at the sanitizer build's -O1 (a quarter of session alignment's time there).
          // Every column of J has a zero, so each sum below has at most two non-zero terms and
          // does not depend on the order of addition: the same values as Eigen's product, bit for bit.
          const double* Jc = J.data();  // column-major: J(k, i) = Jc[3 * i + k]
          for (int i = 0; i < 6; ++i) {
            const double a0 = w * Jc[3 * i], a1 = w * Jc[3 * i + 1], a2 = w * Jc[3 * i + 2];
            for (int j = 0; j < 6; ++j) acc.JTJ(i, j) += a0 * Jc[3 * j] + a1 * Jc[3 * j + 1] + a2 * Jc[3 * j + 2];
            acc.JTr(i) += a0 * r.x() + a1 * r.y() + a2 * r.z();
          }
          ++acc.count;
        }
        return acc;
      },
      [](const NormalEquations& a, const NormalEquations& b) { return a + b; });
}

}  // namespace

IcpResult align_point_to_point(const std::vector<Vec3d>& source, const VoxelHashMap& target, const Pose& initial_guess,
                               const IcpOptions& options) {
  IcpResult result;
  result.T_target_source = initial_guess;
  result.enough_correspondences = true;
  if (source.empty() || target.empty()) {
    result.enough_correspondences = false;
    return result;
  }
  for (int it = 0; it < options.max_iterations; ++it) {
    const NormalEquations eq =
        build_system(source, target, result.T_target_source, options.max_correspondence_distance, options.kernel_scale);
    result.iterations = it + 1;
    result.correspondences = eq.count;
    if (eq.count < options.min_correspondences) {
      result.enough_correspondences = false;
      break;
    }
    const Vector6d dx = eq.JTJ.ldlt().solve(-eq.JTr);
    if (!dx.allFinite()) {
      result.enough_correspondences = false;
      break;
    }
    result.T_target_source = se3_exp(dx) * result.T_target_source;
    if (dx.norm() < options.convergence) {
      result.converged = true;
      break;
    }
  }
  return result;
}

AlignmentQuality alignment_quality(const std::vector<Vec3d>& source, const VoxelHashMap& target,
                                   const Pose& T_target_source, double inlier_distance) {
  struct Sum {
    std::size_t inliers = 0;
    double sq = 0.0;
  };
  const double max2 = inlier_distance * inlier_distance;
  const Sum s = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<std::size_t>(0, source.size(), kGrain), Sum{},
      [&](const tbb::blocked_range<std::size_t>& range, Sum acc) {
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
          Vec3d q;
          double d2;
          if (target.nearest(T_target_source * source[i], q, d2) && d2 <= max2) {
            ++acc.inliers;
            acc.sq += d2;
          }
        }
        return acc;
      },
      [](const Sum& a, const Sum& b) { return Sum{a.inliers + b.inliers, a.sq + b.sq}; });
  AlignmentQuality q;
  q.points = source.size();
  q.inliers = s.inliers;
  q.inlier_rmse = s.inliers ? std::sqrt(s.sq / static_cast<double>(s.inliers)) : 0.0;
  return q;
}

namespace {

struct IcpStage {
  const VoxelHashMap* target;
  const std::vector<Vec3d>* source;
  double max_distance;
};

std::optional<Pose> run_icp_stages(std::span<const IcpStage> stages, const Pose& guess) {
  Pose T = guess;
  for (const IcpStage& stage : stages) {
    IcpOptions icp;
    icp.max_correspondence_distance = stage.max_distance;
    icp.kernel_scale = stage.max_distance / 9.0;
    icp.max_iterations = 50;
    icp.convergence = 1e-3;
    icp.min_correspondences = 50;
    const IcpResult r = align_point_to_point(*stage.source, *stage.target, T, icp);
    if (!r.enough_correspondences) return std::nullopt;
    T = r.T_target_source;
  }
  return T;
}

}  // namespace

std::optional<Pose> align_coarse_to_fine(const std::vector<Vec3d>& source, const VoxelHashMap& coarse_target,
                                         const VoxelHashMap& fine_target, const Pose& guess, double voxel) {
  const std::vector<Vec3d> fine_source = voxel_downsample(source, 2.0 * voxel);
  const std::vector<Vec3d> coarse_source = voxel_downsample(source, 4.0 * voxel);
  const IcpStage stages[] = {{&coarse_target, &coarse_source, 9.0 * voxel}, {&coarse_target, &coarse_source, 4.0 * voxel},
                             {&fine_target, &fine_source, 2.0 * voxel}, {&fine_target, &fine_source, voxel}};
  return run_icp_stages(stages, guess);
}

std::optional<Pose> align_fine(const std::vector<Vec3d>& source, const VoxelHashMap& fine_target, const Pose& guess,
                               double voxel) {
  const std::vector<Vec3d> fine_source = voxel_downsample(source, 2.0 * voxel);
  const IcpStage stages[] = {{&fine_target, &fine_source, 2.0 * voxel}, {&fine_target, &fine_source, voxel}};
  return run_icp_stages(stages, guess);
}

}  // namespace slamvdb::localization
