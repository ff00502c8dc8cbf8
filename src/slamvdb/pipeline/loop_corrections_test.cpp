// Loop corrections while mapping: each submap's anchor ends at the newest correction applied to
// the pose it was anchored on, whatever correction that pose was given with and however often the
// submaps were moved before; merges wait until both submaps are finished and run once per pair.
#include "slamvdb/pipeline/loop_corrections.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace slamvdb {
namespace {

Pose rigid(double yaw, double x, double y) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(x, y, 0);
  return T;
}

SubmapInfo submap(int id, double begin, double end, const Pose& anchor, bool finished = true) {
  SubmapInfo s;
  s.id = id;
  s.time_range.extend(begin), s.time_range.extend(end);
  s.T_world_submap = anchor;
  s.finished = finished;
  return s;
}

TEST(SubmapCorrections, ReplacesTheCorrectionEachAnchorHoldsInsteadOfStackingThem) {
  // Submap 0 anchored on a pose given before any correction, submap 1 on one given after K1.
  const Pose odom0 = rigid(0.1, 1, 2), odom1 = rigid(0.4, 30, -3);
  const Pose K1 = rigid(0.02, 0.5, -0.2), K2 = rigid(-0.03, 0.9, 0.4);
  const auto K2_at = [&](double t) { return t < 10 ? K2 : K2 * rigid(0.01, 0.1, 0); };  // varies along time
  SubmapCorrections c;

  std::vector<SubmapInfo> submaps{submap(0, 0, 9, odom0)};
  std::map<int, Pose> moved = c.move(submaps, [&](double) { return K1; });
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_TRUE(moved.at(0).isApprox(K1 * odom0));
  submaps[0].T_world_submap = moved.at(0);

  c.poses_given_with(10.0, K1);  // from 10 s on the mapper gets K1 * odometry
  submaps.push_back(submap(1, 10, 19, K1 * odom1, false));
  moved = c.move(submaps, K2_at);
  EXPECT_TRUE(moved.at(0).isApprox(K2 * odom0, 1e-12));                  // K1 replaced, not K2 * K1
  EXPECT_TRUE(moved.at(1).isApprox(K2_at(14.5) * odom1, 1e-12));         // its pose came with K1
  EXPECT_EQ(c.report().corrections, 2u);
  EXPECT_EQ(c.report().submaps_moved, 2u);
  EXPECT_GT(c.report().max_shift, 0.3);
}

MergeReport merged_with(double overlap) {
  MergeReport r;
  r.merged = true;
  r.overlap = overlap;
  return r;
}

TEST(SubmapCorrections, MergesWaitForFinishedSubmapsAndFollowEarlierMerges) {
  SubmapCorrections c;
  std::vector<std::pair<int, int>> calls;
  const auto merge = [&](int target, int source) {
    calls.emplace_back(target, source);
    return merged_with(0.7);
  };
  std::vector<SubmapInfo> submaps{submap(0, 0, 9, Pose::Identity()), submap(1, 10, 19, Pose::Identity()),
                                  submap(2, 20, 25, Pose::Identity(), false)};
  c.add_loop(3.0, 24.0);  // joins submap 0 and the active submap 2
  c.merge_ready(submaps, 2, merge);
  EXPECT_TRUE(calls.empty());  // submap 2 is still being written
  EXPECT_EQ(c.pending_loops(), 1u);

  submaps[2] = submap(2, 20, 29, Pose::Identity());
  submaps.push_back(submap(3, 30, 31, Pose::Identity(), false));
  c.add_loop(12.0, 30.5);  // 1 and the active 3
  c.merge_ready(submaps, 3, merge);
  ASSERT_EQ(calls.size(), 1u);
  EXPECT_EQ(calls[0], std::make_pair(0, 2));
  EXPECT_EQ(c.pending_loops(), 1u);

  // Submap 0 absorbed 2 and now spans 0..29 s; a loop at 25 s still means 0, and the loop of
  // 1 and 3 is decided by 1 and 3, not by 0's widened range.
  submaps = {submap(0, 0, 29, Pose::Identity()), submap(1, 10, 19, Pose::Identity()),
             submap(3, 30, 39, Pose::Identity())};
  c.add_loop(25.0, 35.0);
  c.add_loop(2.0, 28.0);  // 0 and 2 (= 0): nothing to merge
  c.merge_ready(submaps, std::nullopt, merge);
  ASSERT_EQ(calls.size(), 3u);
  EXPECT_EQ(calls[1], std::make_pair(1, 3));
  EXPECT_EQ(calls[2], std::make_pair(0, 1));  // 3 went into 1
  EXPECT_EQ(c.pending_loops(), 0u);
  EXPECT_EQ(c.report().merges, 3u);
  EXPECT_EQ(c.report().notes.size(), 3u);
}

}  // namespace
}  // namespace slamvdb
