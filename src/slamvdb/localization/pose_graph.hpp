#pragma once
// SE(3) pose-graph optimisation with Ceres: one vertex per keyframe (T_world_keyframe as a unit
// quaternion + translation on ceres::ProductManifold<EigenQuaternionManifold, EuclideanManifold<3>>),
// relative-pose edges weighted by their information matrix, a robust (Cauchy) loss on the edges
// marked robust (loop closures), the first vertex held fixed.
#include <cstddef>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::localization {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct PoseGraphEdge {
  std::size_t from = 0, to = 0;
  Pose T_from_to = Pose::Identity();           // measured pose of `to` in the frame of `from`
  Matrix6d information = Matrix6d::Identity(); // inverse covariance, twist order (translation, rotation)
  bool robust = false;                         // Cauchy loss (loop closures: a wrong one must not bend the graph)
};

// Information of a relative-pose measurement with independent isotropic translation and rotation
// standard deviations (metres, radians).
Matrix6d isotropic_information(double sigma_translation, double sigma_rotation);

struct PoseGraphOptions {
  int max_iterations = 100;
  // Cauchy scale, in units of the edge's standard deviation: residuals well beyond it count little.
  // Loops are verified before they get here, so the loss only has to stop a rare wrong one; a
  // small scale would also out-vote a true loop that corrects a systematic drift, which the
  // odometry edges (modelled as a random walk) make look improbable.
  double robust_loss_scale = 5.0;
};

struct PoseGraphSummary {
  bool converged = false;
  int iterations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  double seconds = 0.0;
};

class PoseGraph {
 public:
  std::size_t add_vertex(const Pose& T_world_vertex);
  void add_edge(const PoseGraphEdge& edge);  // throws Error on an unknown vertex
  void set_pose(std::size_t vertex, const Pose& T_world_vertex);

  // Optimises every vertex but the first. Throws Error if Ceres reports a failure.
  PoseGraphSummary optimize(const PoseGraphOptions& options = {});

  std::size_t num_vertices() const { return poses_.size(); }
  const std::vector<PoseGraphEdge>& edges() const { return edges_; }
  const Pose& pose(std::size_t vertex) const { return poses_[vertex]; }
  const std::vector<Pose>& poses() const { return poses_; }

 private:
  std::vector<Pose> poses_;
  std::vector<PoseGraphEdge> edges_;
};

}  // namespace slamvdb::localization
