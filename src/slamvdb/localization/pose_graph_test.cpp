#include "slamvdb/localization/pose_graph.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "slamvdb/testing/error_of.hpp"

namespace slamvdb::localization {
namespace {

Pose yaw_step(double forward, double yaw) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(forward, 0.0, 0.0);
  return T;
}

TEST(PoseGraph, OneLoopEdgeRemovesAnInjectedDrift) {
  // A square loop of 40 steps of 1 m (a 90 degree turn every 10), measured with a yaw drift of
  // 0.3 degrees per step and a 1% scale error; one exact loop edge from the last to the first.
  constexpr int kSteps = 40;
  std::vector<Pose> truth{Pose::Identity()};
  for (int i = 1; i <= kSteps; ++i) truth.push_back(truth.back() * yaw_step(1.0, i % 10 == 0 ? std::numbers::pi / 2 : 0.0));
  PoseGraph graph;
  Pose drifted = Pose::Identity();
  graph.add_vertex(drifted);
  const double drift = 0.3 * std::numbers::pi / 180.0;
  for (int i = 1; i <= kSteps; ++i) {
    const Pose measured = truth[i - 1].inverse() * truth[i] * yaw_step(0.01, drift);
    drifted = drifted * measured;
    graph.add_vertex(drifted);
    graph.add_edge({static_cast<std::size_t>(i - 1), static_cast<std::size_t>(i), measured,
                    isotropic_information(0.05, 0.01), false});
  }
  const double error_before = (graph.pose(kSteps).translation() - truth[kSteps].translation()).norm();
  graph.add_edge({0, static_cast<std::size_t>(kSteps), truth[0].inverse() * truth[kSteps],
                  isotropic_information(0.05, 0.005), true});
  const PoseGraphSummary summary = graph.optimize();
  double worst = 0.0;
  for (int i = 0; i <= kSteps; ++i) worst = std::max(worst, (graph.pose(i).translation() - truth[i].translation()).norm());
  EXPECT_GT(error_before, 1.0);
  EXPECT_LT((graph.pose(kSteps).translation() - truth[kSteps].translation()).norm(), 0.05);
  EXPECT_LT(worst, 0.3) << "the drift is spread over the loop, not dumped at its end";
  EXPECT_TRUE(graph.pose(0).isApprox(Pose::Identity())) << "the first vertex is fixed";
  EXPECT_LT(summary.final_cost, summary.initial_cost);
}

TEST(PoseGraph, RobustLossLimitsAWrongLoopEdge) {
  PoseGraph graph;
  for (int i = 0; i <= 20; ++i) graph.add_vertex(yaw_step(i, 0.0));
  for (std::size_t i = 1; i <= 20; ++i) graph.add_edge({i - 1, i, yaw_step(1.0, 0.0), isotropic_information(0.02, 0.002), false});
  // A wrong loop claiming vertex 20 is back at the origin.
  graph.add_edge({0, 20, Pose::Identity(), isotropic_information(0.1, 0.01), true});
  graph.optimize();
  EXPECT_NEAR(graph.pose(20).translation().x(), 20.0, 1.0);
}

TEST(PoseGraph, RejectsBadEdges) {
  PoseGraph graph;
  graph.add_vertex(Pose::Identity());
  EXPECT_NE(slamvdb::testing::error_of([&] { graph.add_edge({0, 1, Pose::Identity(), Matrix6d::Identity(), false}); }), "");
  graph.add_vertex(Pose::Identity());
  EXPECT_NE(slamvdb::testing::error_of([&] { graph.add_edge({0, 1, Pose::Identity(), Matrix6d::Zero(), false}); }), "");
}

}  // namespace
}  // namespace slamvdb::localization
