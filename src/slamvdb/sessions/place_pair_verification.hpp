#pragma once
// The verification of one candidate pair of places of two sessions (session_alignment.hpp): ICP
// between the other place's voxels and the base place's, then the overlap, fitness and structure
// tests. Internal to the alignment of sessions; its own file to keep that one readable.
#include <optional>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/sessions/pair_consensus.hpp"
#include "slamvdb/sessions/place_descriptors.hpp"
#include "slamvdb/sessions/points_near_places.hpp"
#include "slamvdb/sessions/session_alignment.hpp"

namespace slamvdb::sessions {

// One session as the alignment sees it: its submaps' clouds thinned to the places' voxel (the
// verification's) and to the refinement voxel, and its places.
struct AlignmentSession {
  const std::vector<SessionSubmap>* submaps;
  std::vector<std::vector<Vec3d>> clouds;  // thinned to the places' cloud voxel, submap frame
  SubmapClouds dense_clouds;               // thinned to the refinement voxel, submap frame
  std::vector<Pose> T_world_submaps;
  std::vector<Place> places;

  AlignmentSession(const std::vector<SessionSubmap>& s, const AlignmentConfig& config);
  Pose T_world_place(std::size_t place) const {
    const Place& p = places[place];
    return (*submaps)[p.submap].T_world_submap * p.T_submap_place();
  }
  // The place's voxels within `radius`, in the place frame (z above its ground level).
  std::vector<Vec3d> around(std::size_t place, double radius) const {
    return points_around(clouds[places[place].submap], places[place], radius);
  }
  std::vector<Vec3d> dense_around(std::size_t place, double radius) const {
    return points_around(dense_clouds[places[place].submap], places[place], radius);
  }
};

// How a pair is aligned before it is tested: from a descriptor's guess (a yaw only: the four
// coarse-to-fine ICP stages), or from a transform already found (guided: the two fine stages).
enum class PairGuess { kDescriptor, kTransform };

// Verifies one candidate pair from `T_bplace_oplace_guess`; fills `pair` and returns nothing when
// it is accepted, else the first test it failed (the last: agreeing with config.prior, if any).
std::optional<PairRejection> verify_place_pair(const AlignmentSession& base, std::size_t base_place,
                                               const AlignmentSession& other, std::size_t other_place,
                                               const Pose& T_bplace_oplace_guess, PairGuess guess_kind,
                                               const AlignmentConfig& config, VerifiedPair& pair);

}  // namespace slamvdb::sessions
