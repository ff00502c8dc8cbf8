// Alignment of two sessions on SIMULATED maps (slamvdb/testing/simulated_sessions.hpp: a
// procedural terrain along a winding route, cut into 50 m submaps of occupied 0.25 m voxels).
#include <gtest/gtest.h>

#include <chrono>
#include <ctime>
#include <cmath>
#include <cstdint>
#include <set>
#include <tuple>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/sessions/joint_graph.hpp"
#include "slamvdb/sessions/session_alignment.hpp"
#include "slamvdb/testing/simulated_sessions.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb::sessions {
namespace {

// Route lengths (metres), the same in the sanitizer run (SLAMVDB_TEST_SCALE): the cost is the
// number of places (8 per submap at most), and 80 m of route gives as many as 100 m (16).
constexpr int kRouteLength = 100;

// The sanitizer run takes 4 places per submap instead of 8: the time is in verifying the
// candidate pairs (3 per place of the other session), and under ASan each test took 35-56 s.
// The same assertions hold with half the places; the Release suite keeps the default.
AlignmentConfig session_alignment_test_config() {
  AlignmentConfig config;
  config.places.max_places_per_submap = slamvdb::testing::test_size<std::size_t>(8, 4);
  return config;
}
constexpr int kOtherStart = 20;
constexpr int kLookAlikeLength = 120;

using slamvdb::testing::AlignTestWorld;
using slamvdb::testing::make_align_session;
using slamvdb::testing::make_align_test_pose;
using slamvdb::testing::make_align_world;

// The simulated worlds and sessions, built once for the suite (each test only aligns).
struct AlignTestMaps {
  AlignTestWorld world;  // seed 7, winding
  std::vector<SessionSubmap> base;
  // The copy: another world frame (turned 37 degrees, moved), re-voxelised in it, cut into
  // submaps at other places (from metre kOtherStart).
  // 1.35 m in z: the two voxel lattices 0.10 m apart vertically, the worst case measured for
  // point-to-point refinement alone (it locked the lattices, 0.100 m off in z).
  Pose T_other_world = make_align_test_pose(37.0, Vec3d(40.0, -25.0, 1.35));
  std::vector<SessionSubmap> other;
  AlignTestWorld look_alike_world;  // seed 11, repeating every 30 m
  std::vector<SessionSubmap> look_alike_base, look_alike_other;
  // Moved by 12 m along the route (no multiple of 30); 0.4 m in z: the lattices 0.15 m apart
  // (point-to-point refinement alone was 0.10 m off here).
  Pose T_look_alike_other_world = make_align_test_pose(-20.0, Vec3d(12.0, 3.0, 0.4));
};

// Named after align_sessions, not SessionAlignment: a class of that name here would make the
// result type ambiguous to any later file of a unity batch.
class AlignSessions : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    maps_ = new AlignTestMaps;
    maps_->world = make_align_world(7, kRouteLength);
    maps_->base = make_align_session(maps_->world, Pose::Identity(), 0, kRouteLength);
    maps_->other = make_align_session(maps_->world, maps_->T_other_world, kOtherStart, kRouteLength);
    maps_->look_alike_world = make_align_world(11, kLookAlikeLength, 30.0);
    maps_->look_alike_base = make_align_session(maps_->look_alike_world, Pose::Identity(), 0, kLookAlikeLength);
    maps_->look_alike_other =
        make_align_session(maps_->look_alike_world, maps_->T_look_alike_other_world, 30, kLookAlikeLength);
  }
  static void TearDownTestSuite() {
    delete maps_;
    maps_ = nullptr;
  }
  static const AlignTestMaps& maps() { return *maps_; }

 private:
  static inline AlignTestMaps* maps_ = nullptr;
};

TEST_F(AlignSessions, RecoversTheRigidTransformOfAMovedCopy) {
  const AlignTestWorld& world = maps().world;
  const std::vector<SessionSubmap>& base = maps().base;
  const Pose& T_other_world = maps().T_other_world;
  const std::vector<SessionSubmap>& other = maps().other;

  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  const SessionAlignment result = align_sessions(base, other, session_alignment_test_config());
  std::printf("align_sessions: %.2f s wall, %.2f s CPU\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
              static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC);
  for (std::size_t r = 0; r < result.rejections.size(); ++r)
    std::printf("rejected (%s): %zu\n", to_string(static_cast<PairRejection>(r)), result.rejections[r]);
  ASSERT_TRUE(result.aligned) << result.refused;
  const Pose expected = T_other_world.inverse();  // T_base_other
  double worst = 0.0;
  for (const Vec3d& x : world.route) {
    const Vec3d x_other = T_other_world * x;
    worst = std::max(worst, (result.T_base_other * x_other - expected * x_other).norm());
  }
  const double angle = Eigen::AngleAxisd((expected.inverse() * result.T_base_other).linear()).angle();
  const Vec3d mid = T_other_world * world.route[world.route.size() / 2];
  EXPECT_LT(worst, 0.10) << "metres, worst over the route; at its middle: "
                         << (result.T_base_other * mid - expected * mid).transpose();
  EXPECT_LT(std::abs((result.T_base_other * mid - expected * mid).z()), 0.05) << "the lattices locked";
  // No bias along the drive either (a thinning that kept one corner of every coarse cell gave 0.035 m).
  EXPECT_LT((result.T_base_other * mid - expected * mid).norm(), 0.025);
  EXPECT_LT(angle * 180.0 / M_PI, 0.5);
  EXPECT_GE(result.consistent.size(), 3u);
  EXPECT_GT(result.sigma_translation, 0.0);
  EXPECT_LT(result.sigma_translation, 0.5);
  EXPECT_GT(result.overlap, 0.8);
  // Every winning pair alone has the right rotation (a wrong one would have been out-voted).
  for (const std::size_t i : result.consistent)
    EXPECT_LT(Eigen::AngleAxisd((expected.inverse() * result.verified[i].T_base_other).linear()).angle(), 0.035);
  // The joint graph must keep the refined accuracy at every anchor: with the pairs' coarse
  // transforms (verification ICP on 0.5 m clouds) as its evidence it moved them 0.08 m off
  // (worst, through `align`), against 0.007 m for the refined rigid transform.
  EXPECT_FALSE(result.submap_refinements.empty());
  const auto worst_anchor_error = [&](const JointGraphConfig& graph) {
    const std::map<int, Pose> corrected = correct_other_anchors(other, result, graph);
    double out = 0.0;
    for (const SessionSubmap& s : other) {
      const Pose truth = expected * s.T_world_submap;
      out = std::max(out, (corrected.at(s.id).translation() - truth.translation()).norm());
    }
    return out;
  };
  const double anchor_error = worst_anchor_error({});
  JointGraphConfig coarse_graph;
  coarse_graph.use_submap_refinements = false;
  EXPECT_LT(anchor_error, 0.03) << "metres, worst anchor after the joint graph";
  std::printf("SIMULATED joint graph, no drift: worst anchor error %.3f m (with the pairs' coarse transforms %.3f m)\n",
              anchor_error, worst_anchor_error(coarse_graph));
  std::printf("SIMULATED: %zu/%zu places, %zu candidates, %zu verified, %zu consistent, rival %zu, error %.3f m %.3f deg,"
              " sigma %.3f m %.4f deg\n",
              result.base_places, result.other_places, result.candidate_pairs, result.verified.size(),
              result.consistent.size(), result.rival_pairs, worst, angle * 180.0 / M_PI, result.sigma_translation,
              result.sigma_rotation * 180.0 / M_PI);
}

// Large maps verify a survey of every k-th place from the descriptors and the rest guided by its
// winner (AlignmentConfig::survey_places, 48 by default: the test maps' 16 places are too few, so
// the survey is made smaller here: every second place). The same accuracy, with fewer
// verifications from a yaw alone. 8 places per submap also in the sanitizer run: with 4, a survey
// of 4 places may find too little evidence and fall back to every candidate. (A survey that does
// not decide falls back; on look-alike places it refuses as before: the look-alike map here gave
// "ambiguous: 12 ... but 6 others agree on a different one" with a survey of 8.)
TEST_F(AlignSessions, ASurveyOfFewPlacesGuidesTheRestToTheSameAlignment) {
  const std::vector<SessionSubmap>& other = maps().other;
  AlignmentConfig config = session_alignment_test_config();
  config.places.max_places_per_submap = 8;
  config.survey_places = 8;
  const SessionAlignment result = align_sessions(maps().base, other, config);
  ASSERT_TRUE(result.aligned) << result.refused;
  ASSERT_EQ(result.surveyed_places, config.survey_places) << "the survey decided";
  EXPECT_GE(result.guided_pairs, (result.other_places - result.surveyed_places) / 2)
      << "places outside the survey verify guided";
  EXPECT_LT(result.candidate_pairs, config.candidates_per_place * result.other_places);
  const Pose expected = maps().T_other_world.inverse();
  double worst = 0.0;
  for (const Vec3d& x : maps().world.route) {
    const Vec3d x_other = maps().T_other_world * x;
    worst = std::max(worst, (result.T_base_other * x_other - expected * x_other).norm());
  }
  EXPECT_LT(worst, 0.10) << "metres, worst over the route";
  EXPECT_LT(Eigen::AngleAxisd((expected.inverse() * result.T_base_other).linear()).angle() * 180.0 / M_PI, 0.5);
  EXPECT_FALSE(result.submap_refinements.empty());
  std::printf("SIMULATED survey of %zu places: %zu candidates, %zu verified (%zu guided), %zu consistent, error %.3f m\n",
              result.surveyed_places, result.candidate_pairs, result.verified.size(), result.guided_pairs,
              result.consistent.size(), worst);
}

TEST_F(AlignSessions, JointGraphRemovesTheOtherSessionsAnchorDrift) {
  const std::vector<SessionSubmap>& base = maps().base;
  const Pose& T_other_world = maps().T_other_world;
  std::vector<SessionSubmap> other = maps().other;
  // The truth, then a drift of the other session's anchors that grows along its drive (each
  // submap's voxels stay right in its own frame, as with odometry drift).
  std::vector<Pose> truth;
  for (std::size_t i = 0; i < other.size(); ++i) {
    truth.push_back(T_other_world.inverse() * other[i].T_world_submap);
    const double k = static_cast<double>(i);
    other[i].T_world_submap = make_align_test_pose(0.3 * k, Vec3d(0.4 * k, -0.25 * k, 0.08 * k)) * other[i].T_world_submap;
  }
  const SessionAlignment result = align_sessions(base, other, session_alignment_test_config());
  ASSERT_TRUE(result.aligned) << result.refused;
  const std::map<int, Pose> corrected = correct_other_anchors(other, result);
  ASSERT_EQ(corrected.size(), other.size());
  double worst_before = 0.0, worst_after = 0.0, worst_angle_after = 0.0;
  for (std::size_t i = 0; i < other.size(); ++i) {
    const Pose before = result.T_base_other * other[i].T_world_submap;
    const Pose& after = corrected.at(other[i].id);
    worst_before = std::max(worst_before, (before.translation() - truth[i].translation()).norm());
    worst_after = std::max(worst_after, (after.translation() - truth[i].translation()).norm());
    worst_angle_after =
        std::max(worst_angle_after, Eigen::AngleAxisd((truth[i].inverse() * after).linear()).angle() * 180.0 / M_PI);
  }
  EXPECT_GT(worst_before, 0.2) << "the drift is visible after the rigid alignment";
  // 0.015 m measured with each submap's own refinement as the graph's evidence; 0.078 m with the
  // pairs' coarse verification transforms.
  EXPECT_LT(worst_after, 0.05);
  EXPECT_LT(worst_angle_after, 0.5);
  std::printf("SIMULATED anchor drift: worst anchor error %.3f m after the rigid alignment, %.3f m / %.3f deg after "
              "the joint graph\n",
              worst_before, worst_after, worst_angle_after);
}

TEST_F(AlignSessions, AdjustingTheBaseRemovesTheBasesOwnAnchorDrift) {
  // --adjust-base: the base's anchors drifted (growing along its drive, each submap's voxels right
  // in its own frame), the other session's did not. Held fixed, the base keeps its drift; in one
  // graph with the other session's submaps, only its first submap fixed, the consistent other
  // session pulls it back.
  std::vector<SessionSubmap> base = maps().base;
  const std::vector<SessionSubmap>& other = maps().other;
  const Pose T_base_other_truth = maps().T_other_world.inverse();
  ASSERT_GE(base.size(), 2u);
  std::vector<Pose> truth;
  for (std::size_t i = 0; i < base.size(); ++i) {
    truth.push_back(base[i].T_world_submap);
    const double k = static_cast<double>(i);
    base[i].T_world_submap = make_align_test_pose(0.3 * k, Vec3d(0.35 * k, 0.25 * k, 0.08 * k)) * base[i].T_world_submap;
  }
  const SessionAlignment result = align_sessions(base, other, session_alignment_test_config());
  ASSERT_TRUE(result.aligned) << result.refused;
  const JointCorrection both = correct_both_anchors(base, other, result);
  ASSERT_EQ(both.base.size(), base.size());
  ASSERT_EQ(both.other.size(), other.size());
  EXPECT_TRUE(both.base.at(base[0].id).isApprox(base[0].T_world_submap)) << "the base's first submap is held";
  double base_before = 0.0, base_after = 0.0, other_after = 0.0, other_fixed_base = 0.0;
  for (std::size_t i = 0; i < base.size(); ++i) {
    base_before = std::max(base_before, (base[i].T_world_submap.translation() - truth[i].translation()).norm());
    base_after = std::max(base_after, (both.base.at(base[i].id).translation() - truth[i].translation()).norm());
  }
  const std::map<int, Pose> fixed_base = correct_other_anchors(other, result);
  for (const SessionSubmap& s : other) {
    const Vec3d t = (T_base_other_truth * s.T_world_submap).translation();
    other_after = std::max(other_after, (both.other.at(s.id).translation() - t).norm());
    other_fixed_base = std::max(other_fixed_base, (fixed_base.at(s.id).translation() - t).norm());
  }
  EXPECT_GT(base_before, 0.3) << "the drift is there";
  // Measured: 0.668 m before, 0.433 m after; the other session 0.388 m against 0.733 m with the
  // base held. Reduced, not removed: the pairs that tie the other session to the drifted base
  // submap are robust (Cauchy) edges 6-7 sigma off at the start, so the kernel discounts them
  // (docs/multi-session-design.md, "Third step").
  EXPECT_LT(base_after, 0.8 * base_before) << "metres, worst base anchor after the joint graph";
  EXPECT_LT(other_after, 0.7 * other_fixed_base) << "the other session's anchors in the true base world";
  std::printf("SIMULATED base drift: worst base anchor error %.3f m before, %.3f m after --adjust-base; other "
              "session's worst anchor %.3f m (%.3f m with the base held)\n",
              base_before, base_after, other_after, other_fixed_base);
}

TEST_F(AlignSessions, LookAlikePlacesGiveNoFalseAlignment) {
  // Ground and objects repeat every 30 m along a straight route: every place has look-alikes one
  // or more periods away. The copy is moved by 12 m along the route, which is no multiple of 30.
  const AlignTestWorld& world = maps().look_alike_world;
  const std::vector<SessionSubmap>& base = maps().look_alike_base;
  const Pose& T_other_world = maps().T_look_alike_other_world;
  const std::vector<SessionSubmap>& other = maps().look_alike_other;
  const SessionAlignment result = align_sessions(base, other, session_alignment_test_config());
  const Pose expected = T_other_world.inverse();
  if (result.aligned) {  // then it must be the true alignment, not a period away
    const Vec3d x = T_other_world * world.route[world.route.size() / 2];
    EXPECT_LT((result.T_base_other * x - expected * x).norm(), 0.10) << "a false alignment";
  } else {
    EXPECT_NE(result.refused.find("ambiguous"), std::string::npos) << result.refused;
  }
  std::printf("SIMULATED look-alikes: %s (%zu verified, %zu consistent, rival %zu)\n",
              result.aligned ? "aligned" : result.refused.c_str(), result.verified.size(), result.consistent.size(),
              result.rival_pairs);
}

TEST_F(AlignSessions, APriorResolvesLookAlikePlaces) {
  // The look-alike terrain again, now with a prior 2.5 m and 1.5 degrees off (GNSS-like; its
  // error at the far end of the 90 m drive is ~4.5 m): the candidates are the base places near
  // where it puts each place, and the alignment is found.
  const AlignTestWorld& world = maps().look_alike_world;
  const std::vector<SessionSubmap>& base = maps().look_alike_base;
  const Pose& T_other_world = maps().T_look_alike_other_world;
  const std::vector<SessionSubmap>& other = maps().look_alike_other;
  const Pose expected = T_other_world.inverse();
  AlignmentConfig config = session_alignment_test_config();
  config.prior = AlignmentPrior{make_align_test_pose(1.5, Vec3d(2.0, -1.5, 0.0)) * expected, 10.0, 0.52};
  const SessionAlignment result = align_sessions(base, other, config);
  for (std::size_t r = 0; r < result.rejections.size(); ++r)
    std::printf("rejected (%s): %zu\n", to_string(static_cast<PairRejection>(r)), result.rejections[r]);
  ASSERT_TRUE(result.aligned) << result.refused;
  const Vec3d x = T_other_world * world.route[world.route.size() / 2];
  EXPECT_LT((result.T_base_other * x - expected * x).norm(), 0.10)
      << (result.T_base_other * x - expected * x).transpose();
  EXPECT_LT(Eigen::AngleAxisd((expected.inverse() * result.T_base_other).linear()).angle() * 180.0 / M_PI, 0.5);
  std::printf("SIMULATED look-alikes with a prior: %zu candidates, %zu verified, %zu consistent, error %.3f m\n",
              result.candidate_pairs, result.verified.size(), result.consistent.size(),
              (result.T_base_other * x - expected * x).norm());
}

TEST_F(AlignSessions, RefusesMapsThatDoNotOverlap) {
  // Two drives through different (equally built) terrain: nothing in common. At 100 m (seeds 7
  // and 8) three pairs verify and agree, each passing its own tests; the refined overlap (69%)
  // refuses them (AlignmentConfig::min_refined_overlap).
  const AlignTestWorld world_b = make_align_world(8, kRouteLength);
  const std::vector<SessionSubmap>& base = maps().base;
  const std::vector<SessionSubmap> other =
      make_align_session(world_b, make_align_test_pose(-20.0, Vec3d(5, 5, 0)), 0, kRouteLength);
  const SessionAlignment result = align_sessions(base, other, session_alignment_test_config());
  EXPECT_FALSE(result.aligned);
  EXPECT_FALSE(result.refused.empty());
  EXPECT_GT(result.base_places, 0u);
  EXPECT_GT(result.other_places, 0u);
  EXPECT_GT(result.candidate_pairs, 0u) << "the descriptors were compared";
  std::printf("SIMULATED: refused: %s (%zu verified)\n", result.refused.c_str(), result.verified.size());
}

TEST(SessionAlignment, ChecksItsSettings) {
  AlignmentConfig config;
  config.consensus.min_verified_pairs = 1;
  EXPECT_THROW(config.validate(), Error);
  config = {};
  config.places.cloud_voxel = 0.0;
  EXPECT_THROW(config.validate(), Error);
  config = {};
  config.min_refined_overlap = 1.5;
  EXPECT_THROW(config.validate(), Error);
}

}  // namespace
}  // namespace slamvdb::sessions
