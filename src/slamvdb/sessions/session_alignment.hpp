#pragma once
// Where another session's map lies in a base session's world, from the maps alone (no prior):
// places with ScanContext descriptors in both (place_descriptors.hpp), candidate pairs by
// descriptor distance, each verified by coarse-to-fine ICP between the two submaps' voxels
// around the places with an overlap and a fitness (inlier RMSE) test, then a robust consensus over
// the verified pairs: the largest set of pairs that agree on one rigid transform wins, is refined
// by one ICP over all its places, and is refused when it is too small or a disjoint set of
// pairs nearly as large agrees on another transform (look-alike places).
#include <array>
#include <optional>
#include <cstddef>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/sessions/pair_consensus.hpp"
#include "slamvdb/sessions/place_descriptors.hpp"

namespace slamvdb::sessions {

// A prior for the alignment (e.g. GNSS: `align --initial x,y,z,yaw`): candidates are the base
// places within `radius` of where it puts each other place (the guess still from the places'
// descriptors), and a verified pair farther from it than `radius` or `max_rotation` is rejected. The consensus and
// its refusals stay: a prior narrows the search, it does not replace evidence.
struct AlignmentPrior {
  Pose T_base_other = Pose::Identity();
  double radius = 10.0;        // metres
  double max_rotation = 0.52;  // radians (30 degrees)
};

struct AlignmentConfig {
  PlaceConfig places;
  // Candidates: for every place of the other session, the ring-key neighbours among the base's
  // places, re-ranked by the descriptor distance; the best few under the limit are verified.
  std::size_t ring_key_neighbours = 10;
  double max_descriptor_distance = 0.4;
  std::size_t candidates_per_place = 3;
  // On maps with at least twice this many places of the other session, the candidates of every
  // k-th place only (a survey of at least this many places) are verified first; when their
  // consensus wins (its refusals as without a survey), each other place is verified once, against
  // the base place nearest (within guided_radius metres) to where the winner puts it, from the
  // winner's transform (the fine ICP stages only); when it does not, every candidate is verified.
  // 0: every candidate, always. The verifications from a yaw-only guess are the alignment's cost.
  std::size_t survey_places = 48;
  double guided_radius = 10.0;
  // Verification: the other place's voxels at cloud_voxel against the base's at refine_voxel
  // (denser, so that the RMSE of a right alignment stays under max_rmse; two 0.5 m clouds give
  // ~0.2 m whether right or slightly wrong).
  double inlier_distance = 0.3;  // metres
  double min_overlap = 0.5;      // fraction of the other place's voxels on the base's
  double max_rmse = 0.2;         // metres, over those inliers (a right pair: ~0.15 m)
  // Structure: ground alone aligns anywhere (it slides), so a pair must also match the voxels
  // standing above the place's ground level.
  double structure_height = 1.0;          // metres above the place's ground
  std::size_t min_structure_voxels = 50;
  double min_structure_overlap = 0.5;
  ConsensusConfig consensus;
  std::optional<AlignmentPrior> prior;
  // The winning set is refined at this resolution (the maps' voxel size or coarser): metres.
  double refine_voxel = 0.25;
  // Then point-to-plane on the base's surface (surface_refinement.hpp); off only to measure
  // what it corrects.
  bool surface_refinement = true;
  // Points of the other session each refinement step uses at most (ICP and surface step, each an
  // unbiased subset): the refinement over a 3 km map's winning places otherwise uses hundreds of
  // thousands. Per-submap refinements stay under it.
  std::size_t refine_points = 60000;
  // The refined alignment's overlap (the other session's voxels near the winning places that lie
  // on the base's) must reach this, else refused: pairs of two different terrains can agree (3-5
  // pairs of 100-120 m SIMULATED drives on different seeds did, each pair passing its own tests),
  // and then the whole neighbourhood does not match: 0.62-0.69 there, 0.97-1.00 for the same
  // terrain (with 0.5 m of anchor drift too). Calibrated on SIMULATED maps only.
  double min_refined_overlap = 0.8;
  void validate() const;  // throws Error naming the setting
};

// The alignment re-measured on one submap of the other session alone (its voxels near its
// winning places, refined like the whole, from the whole's result): where that submap's anchor
// lies in the base's world, at the refinement's accuracy rather than a verification ICP's on
// 0.5 m clouds. The joint graph's evidence (joint_graph.hpp).
struct SubmapRefinement {
  int other_submap_id = 0;
  Pose T_base_other = Pose::Identity();  // T_base_submap = T_base_other * T_other_submap
  double overlap = 0.0, rmse = 0.0;
  std::size_t pairs = 0;                 // winning pairs found in this submap
};

enum class PairRejection {
  kIcpFailed,
  kLowOverlap,
  kHighRmse,
  kTooLittleStructure,
  kLowStructureOverlap,
  kAgainstPrior,
  kCount
};
const char* to_string(PairRejection reason);

struct SessionAlignment {
  bool aligned = false;
  std::string refused;  // why not, when not aligned (a sentence for the user)
  Pose T_base_other = Pose::Identity();  // maps points of the other session's world into the base's
  // The standard error of the winning pairs' transforms about the result: metres at their places,
  // radians. Zero with one pair (then the alignment is refused anyway by min_verified_pairs >= 2).
  double sigma_translation = 0.0, sigma_rotation = 0.0;
  std::size_t base_places = 0, other_places = 0;
  std::size_t candidate_pairs = 0;         // pairs verified (from descriptors, then guided)
  std::size_t surveyed_places = 0;         // places whose candidates decided (0: all of them)
  std::size_t guided_pairs = 0;            // of the verified pairs, those verified guided by the survey's winner
  std::vector<VerifiedPair> verified;      // every verified pair
  std::vector<std::size_t> consistent;     // indices into verified: the winning set
  std::size_t rival_pairs = 0;             // the largest set disjoint from the winner
  std::array<std::size_t, static_cast<std::size_t>(PairRejection::kCount)> rejections{};
  double overlap = 0.0, rmse = 0.0;        // of the refined alignment over the winning places
  // When aligned: one per other submap with winning pairs whose own refinement reached
  // min_refined_overlap, by submap id (the others keep only their pairs' coarse transforms).
  std::vector<SubmapRefinement> submap_refinements;
};

// Aligns `other` to `base` (each a session's submaps, anchors in its own world). Deterministic.
SessionAlignment align_sessions(const std::vector<SessionSubmap>& base, const std::vector<SessionSubmap>& other,
                                const AlignmentConfig& config = {});

}  // namespace slamvdb::sessions
