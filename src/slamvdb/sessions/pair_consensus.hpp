#pragma once
// The robust step of aligning two sessions: which verified place pairs agree on one rigid
// transform between the two worlds, and whether that evidence suffices. The result is the
// largest agreeing set, not a mean over all pairs, so one wrong pair cannot bend it; a second,
// disjoint agreeing set nearly as large (look-alike places) makes the evidence ambiguous.
#include <cstddef>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::sessions {

struct VerifiedPair {
  std::size_t base_place = 0, other_place = 0;  // indices into the sessions' places
  int base_submap_id = 0, other_submap_id = 0;
  Vec3d other_place_world = Vec3d::Zero();  // where the pair was measured, in the other session's world
  Pose T_base_other = Pose::Identity();     // the two worlds, from this pair alone
  double descriptor_distance = 1.0;
  double overlap = 0.0, rmse = 0.0, structure_overlap = 0.0;
};

struct ConsensusConfig {
  // Two pairs agree when their rotations differ by at most consensus_rotation and their
  // transforms move both pairs' places to within consensus_translation of each other (a lever
  // arm test: raw translations depend on where the world origins are).
  double consensus_translation = 1.0;  // metres
  double consensus_rotation = 0.035;   // radians (2 degrees)
  std::size_t min_verified_pairs = 3;  // distinct places of the other session in the winning set
  // Refused as ambiguous when a set disjoint from the winner, agreeing within itself, has at
  // least 2 pairs and this fraction of the winner's.
  double ambiguity_ratio = 0.5;
  // Also ambiguous when more than this fraction of the winner's places verified as well against
  // base places at a transform outside the winning set: each such place alone cannot tell which
  // is right (a repeated arrangement verifies at every repeat; the sets of the repeats need not
  // be of similar size, since a place's candidates are only its best few).
  double max_ambiguous_place_fraction = 0.5;
  void validate() const;  // throws Error naming the setting
};

struct PairConsensus {
  std::vector<std::size_t> winners;  // indices into the pairs, ascending
  std::size_t best = 0;              // the pair the winners agree with
  std::size_t rival_pairs = 0;       // the largest agreeing set among the others
  std::size_t winner_places = 0;     // distinct other places in the winning set
  std::size_t ambiguous_places = 0;  // of those, places with a verified pair outside the winning set
  std::string refused;               // empty when the evidence suffices
};

PairConsensus find_pair_consensus(const std::vector<VerifiedPair>& pairs, const ConsensusConfig& config);

// Whether two pairs agree: rotations within consensus_rotation, and both places moved by either
// transform to within consensus_translation of each other.
bool verified_pairs_agree(const VerifiedPair& a, const VerifiedPair& b, const ConsensusConfig& config);

}  // namespace slamvdb::sessions
