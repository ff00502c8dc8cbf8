#include "slamvdb/sessions/pair_consensus.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace slamvdb::sessions {
namespace {

Pose consensus_test_pose(double yaw, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// A pair measured at the other session's place `place` (on a line, 20 m apart), whose transform
// is `T` disturbed by a few centimetres and a few hundredths of a degree.
VerifiedPair consensus_test_pair(std::size_t place, const Pose& T, double rmse = 0.1) {
  VerifiedPair pair;
  pair.other_place = place;
  pair.other_place_world = Vec3d(20.0 * static_cast<double>(place), 5.0, 0.0);
  const double e = 0.01 * std::sin(3.0 * static_cast<double>(place) + 1.0);
  pair.T_base_other = consensus_test_pose(0.0005 * std::cos(static_cast<double>(place)), Vec3d(e, -e, 0.5 * e)) * T;
  pair.rmse = rmse;
  return pair;
}

const Pose kConsensusTruth = consensus_test_pose(0.6, Vec3d(40.0, -25.0, 1.3));
const Pose kConsensusLookAlike = consensus_test_pose(0.6, Vec3d(70.0, -25.0, 1.3));  // one repeat (30 m) further

TEST(PairConsensus, OneWrongPairIsOutvotedNotAveraged) {
  std::vector<VerifiedPair> pairs;
  for (std::size_t p = 0; p < 5; ++p) pairs.push_back(consensus_test_pair(p, kConsensusTruth));
  pairs.insert(pairs.begin() + 2, consensus_test_pair(7, kConsensusLookAlike, 0.01));  // wrong, with the best fit
  const PairConsensus c = find_pair_consensus(pairs, {});
  EXPECT_TRUE(c.refused.empty()) << c.refused;
  EXPECT_EQ(c.winners, (std::vector<std::size_t>{0, 1, 3, 4, 5}));
  EXPECT_NE(c.best, 2u);
  EXPECT_EQ(c.rival_pairs, 1u);
  EXPECT_EQ(c.winner_places, 5u);
  // The best pair's transform is the truth's, to the disturbance: the wrong one did not move it.
  EXPECT_LT((pairs[c.best].T_base_other.translation() - kConsensusTruth.translation()).norm(), 0.05);
}

TEST(PairConsensus, TwoAgreeingSetsOfLookAlikePlacesAreAmbiguous) {
  std::vector<VerifiedPair> pairs;
  for (std::size_t p = 0; p < 4; ++p) pairs.push_back(consensus_test_pair(p, kConsensusTruth));
  for (std::size_t p = 4; p < 7; ++p) pairs.push_back(consensus_test_pair(p, kConsensusLookAlike));
  const PairConsensus c = find_pair_consensus(pairs, {});
  EXPECT_EQ(c.winners.size(), 4u);
  EXPECT_EQ(c.rival_pairs, 3u);
  EXPECT_NE(c.refused.find("ambiguous"), std::string::npos) << c.refused;
  // A rival of 2 pairs against 7 is tolerated at ratio 0.5.
  pairs.resize(4 + 2);
  for (std::size_t p = 7; p < 10; ++p) pairs.push_back(consensus_test_pair(p, kConsensusTruth));
  EXPECT_TRUE(find_pair_consensus(pairs, {}).refused.empty());
}

TEST(PairConsensus, PlacesThatVerifyAtSeveralAlignmentsAreAmbiguous) {
  // Every place verifies at the truth and at a look-alike; the look-alikes scatter over several
  // repeats, so no single rival set is large, but no place can tell which is right.
  std::vector<VerifiedPair> pairs;
  for (std::size_t p = 0; p < 6; ++p) {
    pairs.push_back(consensus_test_pair(p, kConsensusTruth));
    const Pose repeat = consensus_test_pose(0.6, Vec3d(40.0 + 30.0 * static_cast<double>(1 + p % 3), -25.0, 1.3));
    pairs.push_back(consensus_test_pair(p, repeat));
  }
  const PairConsensus c = find_pair_consensus(pairs, {});
  EXPECT_EQ(c.winner_places, 6u);
  EXPECT_EQ(c.rival_pairs, 2u);  // under the ratio rule's threshold (3)
  EXPECT_EQ(c.ambiguous_places, 6u);
  EXPECT_NE(c.refused.find("ambiguous"), std::string::npos) << c.refused;
}

TEST(PairConsensus, PairsFromOnePlaceAreNotEnoughEvidence) {
  std::vector<VerifiedPair> pairs;
  for (int k = 0; k < 4; ++k) pairs.push_back(consensus_test_pair(3, kConsensusTruth));  // one place, four base places
  pairs.push_back(consensus_test_pair(4, kConsensusTruth));
  const PairConsensus c = find_pair_consensus(pairs, {});
  EXPECT_EQ(c.winners.size(), 5u);
  EXPECT_EQ(c.winner_places, 2u);
  EXPECT_NE(c.refused.find("too little evidence"), std::string::npos) << c.refused;
  EXPECT_FALSE(find_pair_consensus({}, {}).refused.empty());
}

TEST(PairConsensus, AgreementIsMeasuredAtThePlacesNotAtTheOrigin) {
  // A rotation difference of 1 degree moves a place 1 km from the origin by 17 m: no agreement,
  // although the rotations alone are within the 2 degree tolerance.
  VerifiedPair a = consensus_test_pair(0, kConsensusTruth), b = consensus_test_pair(1, kConsensusTruth);
  a.other_place_world = b.other_place_world = Vec3d(1000.0, 0.0, 0.0);
  b.T_base_other = consensus_test_pose(0.6 + 0.0175, kConsensusTruth.translation());
  a.T_base_other = kConsensusTruth;
  const PairConsensus c = find_pair_consensus({a, b}, {.consensus_translation = 1.0, .consensus_rotation = 0.035,
                                                      .min_verified_pairs = 2, .ambiguity_ratio = 0.5,
                                                      .max_ambiguous_place_fraction = 0.5});
  EXPECT_EQ(c.winners.size(), 1u);
  EXPECT_FALSE(c.refused.empty());
}

}  // namespace
}  // namespace slamvdb::sessions
