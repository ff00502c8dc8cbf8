#include "slamvdb/localization/pose_graph.hpp"

#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <ceres/product_manifold.h>
#include <fmt/format.h>

#include <Eigen/Cholesky>
#include <array>

#include "slamvdb/core/error.hpp"

namespace slamvdb::localization {

Matrix6d isotropic_information(double sigma_translation, double sigma_rotation) {
  Matrix6d info = Matrix6d::Zero();
  info.diagonal() << Eigen::Vector3d::Constant(1.0 / (sigma_translation * sigma_translation)),
      Eigen::Vector3d::Constant(1.0 / (sigma_rotation * sigma_rotation));
  return info;
}

namespace {

// A vertex as 7 numbers: Eigen quaternion storage (x, y, z, w), then the translation.
using VertexState = std::array<double, 7>;

VertexState to_state(const Pose& T) {
  const Eigen::Quaterniond q(T.linear());
  return {q.x(), q.y(), q.z(), q.w(), T.translation().x(), T.translation().y(), T.translation().z()};
}

Pose from_state(const VertexState& s) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::Quaterniond(s[3], s[0], s[1], s[2]).normalized().toRotationMatrix();
  T.translation() = Vec3d(s[4], s[5], s[6]);
  return T;
}

// Residual of a relative-pose edge: the measured T_a_b against the estimate T_world_a^-1 T_world_b,
// as (translation difference in a's frame, 2 * vector part of the rotation difference), whitened.
struct RelativePoseError {
  RelativePoseError(const Pose& T_a_b, const Matrix6d& sqrt_information)
      : p_ab(T_a_b.translation()), q_ab(T_a_b.linear()), sqrt_info(sqrt_information) {}

  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(a), q_b(b);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(a + 4), p_b(b + 4);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Matrix<T, 3, 1> p_ab_est = q_a_inv * (p_b - p_a);
    const Eigen::Quaternion<T> dq = q_ab.template cast<T>().conjugate() * (q_a_inv * q_b);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r.template head<3>() = p_ab_est - p_ab.template cast<T>();
    r.template tail<3>() = T(2.0) * dq.vec();
    r.applyOnTheLeft(sqrt_info.template cast<T>());
    return true;
  }

  Vec3d p_ab;
  Eigen::Quaterniond q_ab;
  Matrix6d sqrt_info;
};

}  // namespace

std::size_t PoseGraph::add_vertex(const Pose& T_world_vertex) {
  poses_.push_back(T_world_vertex);
  return poses_.size() - 1;
}

void PoseGraph::set_pose(std::size_t vertex, const Pose& T_world_vertex) {
  if (vertex >= poses_.size()) throw Error(fmt::format("pose graph has no vertex {}", vertex));
  poses_[vertex] = T_world_vertex;
}

void PoseGraph::add_edge(const PoseGraphEdge& edge) {
  if (edge.from >= poses_.size() || edge.to >= poses_.size() || edge.from == edge.to)
    throw Error(fmt::format("pose graph edge {} -> {} needs two distinct vertices of {}", edge.from, edge.to,
                            poses_.size()));
  if (!edge.information.allFinite() || edge.information.llt().info() != Eigen::Success)
    throw Error(fmt::format("pose graph edge {} -> {}: information matrix is not positive definite", edge.from,
                            edge.to));
  edges_.push_back(edge);
}

PoseGraphSummary PoseGraph::optimize(const PoseGraphOptions& options) {
  PoseGraphSummary summary;
  if (poses_.size() < 2 || edges_.empty()) {
    summary.converged = true;
    return summary;
  }
  std::vector<VertexState> states;
  states.reserve(poses_.size());
  for (const Pose& T : poses_) states.push_back(to_state(T));

  ceres::Problem problem;  // owns the manifold and the losses
  auto* manifold = new ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>>(
      ceres::EigenQuaternionManifold{}, ceres::EuclideanManifold<3>{});
  for (const PoseGraphEdge& e : edges_) {
    const Matrix6d sqrt_info = e.information.llt().matrixU();
    auto* cost = new ceres::AutoDiffCostFunction<RelativePoseError, 6, 7, 7>(new RelativePoseError(e.T_from_to, sqrt_info));
    ceres::LossFunction* loss = e.robust ? new ceres::CauchyLoss(options.robust_loss_scale) : nullptr;
    problem.AddResidualBlock(cost, loss, states[e.from].data(), states[e.to].data());
  }
  for (auto& s : states)
    if (problem.HasParameterBlock(s.data())) problem.SetManifold(s.data(), manifold);
  if (problem.HasParameterBlock(states[0].data())) problem.SetParameterBlockConstant(states[0].data());

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver.max_num_iterations = options.max_iterations;
  solver.num_threads = 1;  // small problems; one thread keeps the result bit-identical
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary report;
  ceres::Solve(solver, &problem, &report);
  if (report.termination_type == ceres::FAILURE || !report.IsSolutionUsable())
    throw Error("pose-graph optimisation failed: " + report.message);
  summary.converged = report.termination_type == ceres::CONVERGENCE;
  summary.iterations = static_cast<int>(report.iterations.size());
  summary.initial_cost = report.initial_cost;
  summary.final_cost = report.final_cost;
  summary.seconds = report.total_time_in_seconds;
  for (std::size_t i = 0; i < poses_.size(); ++i) poses_[i] = from_state(states[i]);
  return summary;
}

}  // namespace slamvdb::localization
