// The alignment's refinements read surface planes fitted once (session_refinement.hpp) and run in
// parallel: on a SIMULATED map, each submap's refinement (two threads) must equal the one made on
// a base of its own places alone, planes included (one thread).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <optional>
#include <set>
#include <vector>

#include "slamvdb/sessions/place_pair_verification.hpp"
#include "slamvdb/sessions/session_alignment.hpp"
#include "slamvdb/sessions/session_refinement.hpp"
#include "slamvdb/testing/simulated_sessions.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb::sessions {
namespace {

using slamvdb::testing::make_align_session;
using slamvdb::testing::make_align_test_pose;
using slamvdb::testing::make_align_world;

// 100 m of route (two submaps a session); 4 places per submap under the sanitizers (the time is
// in verifying the candidates), 8 in Release.
AlignmentConfig refinement_test_config() {
  AlignmentConfig config;
  config.places.max_places_per_submap = slamvdb::testing::test_size<std::size_t>(8, 4);
  return config;
}

TEST(SessionRefinement, SharedPlanesRefineEachSubmapAsItsOwnBaseWould) {
  const slamvdb::testing::AlignTestWorld world = make_align_world(7, 100);
  const std::vector<SessionSubmap> base = make_align_session(world, Pose::Identity(), 0, 100);
  const std::vector<SessionSubmap> other =
      make_align_session(world, make_align_test_pose(37.0, Vec3d(40.0, -25.0, 1.35)), 20, 100);
  const AlignmentConfig config = refinement_test_config();

  const SessionAlignment two = [&] {
    const tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
    return align_sessions(base, other, config);
  }();
  ASSERT_TRUE(two.aligned) << two.refused;
  ASSERT_FALSE(two.submap_refinements.empty());

  // Each submap's refinement on a base of its own winning places (the voxels and planes it
  // reads), from the whole's result, on one thread: the shared planes read by refinements in
  // parallel must give the same transform.
  const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  const AlignmentSession base_session(base, config), other_session(other, config);
  for (const SubmapRefinement& shared : two.submap_refinements) {
    std::optional<std::size_t> index;
    for (std::size_t i = 0; i < other.size(); ++i)
      if (other[i].id == shared.other_submap_id) index = i;
    ASSERT_TRUE(index);
    std::set<std::size_t> base_places, other_places;
    winning_places(other_session, two.verified, two.consistent, index, base_places, other_places);
    RefinementBase own(base_session, base_places, config);
    const RefinementSource source = refinement_source(other_session, other_places, config, index);
    own.add_planes_near(source, two.T_base_other);
    const RefinedClouds alone = own.refine(source, two.T_base_other, /*from_refined=*/true);
    EXPECT_LT((alone.T_base_other.translation() - shared.T_base_other.translation()).norm(), 1e-6)
        << "submap " << shared.other_submap_id;
    EXPECT_LT(Eigen::AngleAxisd(alone.T_base_other.linear().transpose() * shared.T_base_other.linear()).angle(), 1e-8);
    EXPECT_NEAR(alone.overlap, shared.overlap, 1e-9);
    // And the refinement moved it (else the comparison above would hold for any base).
    EXPECT_GT((shared.T_base_other.translation() - two.T_base_other.translation()).norm(), 1e-5);
  }
}

}  // namespace
}  // namespace slamvdb::sessions
