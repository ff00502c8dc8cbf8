#include "slamvdb/sessions/session_alignment.hpp"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/localization/preprocessing.hpp"
#include "slamvdb/localization/registration.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"
#include "slamvdb/sessions/place_pair_verification.hpp"
#include "slamvdb/sessions/points_near_places.hpp"
#include "slamvdb/sessions/surface_refinement.hpp"

namespace slamvdb::sessions {

using localization::VoxelHashMap;

void AlignmentConfig::validate() const {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("invalid alignment setting: " + what);
  };
  places.validate();
  require(ring_key_neighbours > 0 && candidates_per_place > 0, "ring-key neighbours and candidates per place must be > 0");
  require(max_descriptor_distance > 0.0 && max_descriptor_distance <= 1.0, "max descriptor distance must be in (0, 1]");
  require(inlier_distance > 0.0 && max_rmse > 0.0, "inlier distance and max RMSE must be > 0");
  require(min_overlap > 0.0 && min_overlap <= 1.0, fmt::format("min overlap {} must be in (0, 1]", min_overlap));
  require(min_structure_overlap >= 0.0 && min_structure_overlap <= 1.0, "min structure overlap must be in [0, 1]");
  require(guided_radius > 0.0, fmt::format("guided radius {} m must be > 0", guided_radius));
  require(refine_points >= 1000, fmt::format("refine points {} must be >= 1000", refine_points));
  require(refine_voxel > 0.0, fmt::format("refine voxel {} m must be > 0", refine_voxel));
  require(min_refined_overlap >= 0.0 && min_refined_overlap <= 1.0,
          fmt::format("min refined overlap {} must be in [0, 1]", min_refined_overlap));
  consensus.validate();
  if (prior) {
    require(prior->radius > 0.0 && prior->max_rotation > 0.0, "the prior's radius and rotation must be > 0");
    require(prior->T_base_other.matrix().allFinite(), "the prior must be finite");
  }
}

const char* to_string(PairRejection reason) {
  switch (reason) {
    case PairRejection::kIcpFailed: return "ICP failed";
    case PairRejection::kLowOverlap: return "low overlap";
    case PairRejection::kHighRmse: return "high RMSE";
    case PairRejection::kTooLittleStructure: return "too little structure";
    case PairRejection::kLowStructureOverlap: return "low structure overlap";
    case PairRejection::kAgainstPrior: return "against the prior";
    case PairRejection::kCount: break;
  }
  return "?";
}

namespace {

Pose yaw_pose(double yaw) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Vec3d::UnitZ()).toRotationMatrix();
  return T;
}

double rotation_angle(const Pose& T) { return Eigen::AngleAxisd(T.linear()).angle(); }

// Every submap's voxels (thinned to `voxel`) within `radius` (horizontally) of any of the places,
// in the world frame of the session. All submaps, not only the places' own: a place's
// surroundings cut at its submap's edge would pull the other session's points inwards. With
// `only_submap` (an index), that submap's voxels alone.
std::vector<Vec3d> session_cloud_near(const AlignmentSession& session, const std::set<std::size_t>& places,
                                      double radius, double voxel, std::optional<std::size_t> only_submap = {}) {
  std::vector<Eigen::Vector2d> centres;
  for (const std::size_t p : places) centres.push_back(session.T_world_place(p).translation().head<2>());
  return localization::voxel_downsample(
      session.dense_clouds.world_points_near(session.T_world_submaps, centres, radius, only_submap), voxel);
}

// Every `keep_one_in`-th point on average, chosen by a hash of its index: a subset with no
// geometric pattern. Thinning by keeping the first point of each coarser voxel picks, from
// voxels stored in key order, the same corner of every coarse cell, and that biased the
// refinement by 0.035 m along the drive (on sloped ground the kept voxels sit on one side).
std::vector<Vec3d> unbiased_subset(const std::vector<Vec3d>& points, uint64_t keep_one_in) {
  std::vector<Vec3d> out;
  out.reserve(points.size() / keep_one_in + 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    uint64_t z = (static_cast<uint64_t>(i) + 1) * 0x9E3779B97F4A7C15ULL;  // splitmix64's finaliser
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    if ((z ^ (z >> 31)) % keep_one_in == 0) out.push_back(points[i]);
  }
  return out;
}

struct RefinedClouds {
  Pose T_base_other = Pose::Identity();
  double overlap = 0.0, rmse = 0.0;
};

// ICP of the other session's points onto the base's (both world frames) at the refinement
// resolution, from 2 cloud voxels down to one refinement voxel, then the surface step.
RefinedClouds refine_clouds(const std::vector<Vec3d>& base_points, const std::vector<Vec3d>& other_points,
                            const Pose& start, const AlignmentConfig& config) {
  const double voxel = config.refine_voxel;
  VoxelHashMap target(voxel, 1e9, 20);
  target.add_points(base_points);
  // The source at twice the cloud voxel: the dense target gives each of its points a near
  // neighbour, and every point costs 27 hash look-ups per iteration (the refinement was half
  // the alignment's time with the source at the cloud voxel, for no gain in accuracy).
  // At most refine_points of them (an unbiased subset): a rigid transform over a whole map is
  // fixed long before every metre of a 3 km drive is used, and the cost grows with the points.
  const std::vector<Vec3d> downsampled = localization::voxel_downsample(other_points, 2.0 * config.places.cloud_voxel);
  const std::vector<Vec3d> source = downsampled.size() > config.refine_points
                                        ? unbiased_subset(downsampled, (downsampled.size() + config.refine_points - 1) /
                                                                           config.refine_points)
                                        : downsampled;
  Pose T = start;
  for (const double distance : {2.0 * config.places.cloud_voxel, config.places.cloud_voxel, voxel}) {
    localization::IcpOptions icp;
    icp.max_correspondence_distance = distance;
    icp.kernel_scale = distance / 9.0;
    icp.max_iterations = 30;
    icp.convergence = 1e-5;
    icp.min_correspondences = 50;
    const localization::IcpResult r = localization::align_point_to_point(source, target, T, icp);
    if (!r.enough_correspondences) break;  // keep the last good transform
    T = r.T_target_source;
  }
  if (config.surface_refinement) {
    // Point-to-point between two voxel-centre lattices locks them together (surface_refinement.hpp):
    // the last step puts the other session's voxels on the base's surface planes: a quarter of
    // them (each a voxel centre as stored), picked without a geometric pattern.
    SurfaceRefinementConfig surface;
    surface.voxel = voxel;
    surface.normal_radius = 2.4 * voxel;
    surface.max_distance = voxel;
    const std::vector<Vec3d> surface_source = unbiased_subset(
        other_points, std::max<uint64_t>(4, (other_points.size() + config.refine_points - 1) / config.refine_points));
    std::vector<Vec3d> surface_start;
    surface_start.reserve(surface_source.size());
    for (const Vec3d& p : surface_source) surface_start.push_back(T * p);
    const SurfacePlanes planes(base_points, surface_start, surface);
    const SurfaceRefinement refined = refine_on_surface(surface_source, planes, T, surface);
    if (refined.ok) T = refined.T_base_other;
  }
  const localization::AlignmentQuality quality = localization::alignment_quality(source, target, T, config.inlier_distance);
  return {T, quality.inlier_fraction(), quality.inlier_rmse};
}

// Refines the winner over all its places (`only_other_submap`: over that other submap's places
// and voxels alone). The base reaches farther than the other session's places, so that every
// point of those finds its true neighbour.
RefinedClouds refine_places(const AlignmentSession& base, const AlignmentSession& other,
                            const std::vector<VerifiedPair>& pairs, const std::vector<std::size_t>& winners,
                            const Pose& start, const AlignmentConfig& config,
                            std::optional<std::size_t> only_other_submap = {}) {
  const double radius = config.places.scan_context.max_radius;
  std::set<std::size_t> base_places, other_places;
  for (const std::size_t i : winners) {
    if (only_other_submap && other.places[pairs[i].other_place].submap != *only_other_submap) continue;
    base_places.insert(pairs[i].base_place);
    other_places.insert(pairs[i].other_place);
  }
  return refine_clouds(session_cloud_near(base, base_places, radius + 10.0, config.refine_voxel),
                       session_cloud_near(other, other_places, radius, config.refine_voxel, only_other_submap), start,
                       config);
}

// Every place of the other session outside the survey (not a multiple of `step`), verified once:
// against the base place nearest (within guided_radius) to where the survey's winner puts it, from
// that transform (only the fine ICP stages). Its pairs that agree with the winner join the winners;
// the survey alone was judged for ambiguity.
void add_guided_pairs(const AlignmentSession& base, const AlignmentSession& other, std::size_t step,
                      const AlignmentConfig& config, SessionAlignment& result, PairConsensus& consensus) {
  const Pose T_survey = result.verified[consensus.best].T_base_other;
  struct Guided {
    std::size_t base_place, other_place;
    Pose guess;
  };
  std::vector<Guided> guided;
  for (std::size_t j = 0; j < other.places.size(); ++j) {
    if (j % step == 0) continue;
    const Pose T_base_oplace = T_survey * other.T_world_place(j);
    std::optional<std::size_t> nearest;
    double nearest_distance = config.guided_radius;
    for (std::size_t i = 0; i < base.places.size(); ++i) {
      const double d = (base.T_world_place(i).translation() - T_base_oplace.translation()).head<2>().norm();
      if (d <= nearest_distance) {
        nearest = i;
        nearest_distance = d;
      }
    }
    if (nearest) guided.push_back({*nearest, j, base.T_world_place(*nearest).inverse() * T_base_oplace});
  }
  std::vector<VerifiedPair> checked(guided.size());
  std::vector<std::optional<PairRejection>> rejections(guided.size());
  tbb::parallel_for(std::size_t{0}, guided.size(), [&](std::size_t g) {
    rejections[g] = verify_place_pair(base, guided[g].base_place, other, guided[g].other_place, guided[g].guess,
                                      PairGuess::kTransform, config, checked[g]);
  });
  result.candidate_pairs += guided.size();
  const VerifiedPair winner = result.verified[consensus.best];
  for (std::size_t g = 0; g < guided.size(); ++g) {
    if (rejections[g]) {
      ++result.rejections[static_cast<std::size_t>(*rejections[g])];
      continue;
    }
    ++result.guided_pairs;
    if (verified_pairs_agree(winner, checked[g], config.consensus)) consensus.winners.push_back(result.verified.size());
    result.verified.push_back(checked[g]);
  }
}

}  // namespace

SessionAlignment align_sessions(const std::vector<SessionSubmap>& base_submaps,
                                const std::vector<SessionSubmap>& other_submaps, const AlignmentConfig& config) {
  config.validate();
  const AlignmentSession base(base_submaps, config), other(other_submaps, config);
  SessionAlignment result;
  result.base_places = base.places.size();
  result.other_places = other.places.size();

  localization::ScanContextDatabase database(config.places.scan_context);
  for (const Place& p : base.places) database.add(p.descriptor);
  // The candidate pairs first (cheap), then their verification ICPs in parallel (the alignment's
  // cost: 3 per place of the other session), the results taken in the candidates' order.
  struct Candidate {
    std::size_t base_place, other_place;
    Pose guess;
    double descriptor_distance;
  };
  std::vector<Candidate> candidates;
  for (std::size_t j = 0; j < other.places.size(); ++j) {
    if (config.prior) {
      // The base places nearest to where the prior puts this place. The guess still comes from
      // the descriptors (the places' centres and the ScanContext yaw): places are modes of the
      // same surfaces, closer than the prior's metres, and ICP from a guess metres off slides
      // along the ground.
      const Pose T_base_oplace = config.prior->T_base_other * other.T_world_place(j);
      std::vector<std::pair<double, std::size_t>> near;
      for (std::size_t i = 0; i < base.places.size(); ++i) {
        const double d = (base.T_world_place(i).translation() - T_base_oplace.translation()).head<2>().norm();
        if (d <= config.prior->radius) near.push_back({d, i});
      }
      std::sort(near.begin(), near.end());
      for (std::size_t k = 0; k < near.size() && k < config.candidates_per_place; ++k) {
        const localization::ScanContextMatch match = localization::compare_scan_contexts(
            other.places[j].descriptor, base.places[near[k].second].descriptor, config.places.scan_context);
        candidates.push_back({near[k].second, j, yaw_pose(match.yaw), match.distance});
      }
      continue;
    }
    if (database.size() == 0) break;
    const auto found = database.query(other.places[j].descriptor, database.size(), config.ring_key_neighbours,
                                      config.max_descriptor_distance);
    for (std::size_t k = 0; k < found.size() && k < config.candidates_per_place; ++k)
      candidates.push_back({found[k].index, j, yaw_pose(found[k].match.yaw), found[k].match.distance});
  }
  // Verified from their descriptors' candidates: every place's, or on a map with many places a
  // survey's, every k-th place (at least survey_places of them; the ICPs from a yaw-only guess are
  // the alignment's cost). The survey's consensus decides, with its refusals; when it wins, every
  // other place is verified once, against the base place where the winner puts it and from the
  // winner's transform (guided). When the survey does not decide, every candidate is verified.
  const std::size_t step = config.survey_places == 0 || other.places.size() < 2 * config.survey_places
                               ? 1
                               : other.places.size() / config.survey_places;
  std::vector<VerifiedPair> checked(candidates.size());
  std::vector<std::optional<PairRejection>> rejections(candidates.size());
  std::vector<char> done(candidates.size(), 0);
  const auto verify_candidates = [&](bool survey_only) {
    std::vector<std::size_t> todo;
    for (std::size_t c = 0; c < candidates.size(); ++c)
      if (!done[c] && (!survey_only || candidates[c].other_place % step == 0)) todo.push_back(c);
    tbb::parallel_for(std::size_t{0}, todo.size(), [&](std::size_t t) {
      const std::size_t c = todo[t];
      const Candidate& candidate = candidates[c];
      checked[c].descriptor_distance = candidate.descriptor_distance;
      rejections[c] = verify_place_pair(base, candidate.base_place, other, candidate.other_place, candidate.guess,
                                        PairGuess::kDescriptor, config, checked[c]);
      done[c] = 1;
    });
    // The results in the candidates' order, whatever the order of verification.
    result.verified.clear();
    result.rejections = {};
    result.candidate_pairs = 0;
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      if (!done[c]) continue;
      ++result.candidate_pairs;
      if (rejections[c])
        ++result.rejections[static_cast<std::size_t>(*rejections[c])];
      else
        result.verified.push_back(checked[c]);
    }
  };
  verify_candidates(step > 1);
  std::vector<VerifiedPair>& pairs = result.verified;
  PairConsensus consensus;
  if (!pairs.empty()) consensus = find_pair_consensus(pairs, config.consensus);
  if (step > 1 && (pairs.empty() || !consensus.refused.empty())) {
    verify_candidates(false);
    if (!pairs.empty()) consensus = find_pair_consensus(pairs, config.consensus);
  } else if (step > 1) {
    result.surveyed_places = (other.places.size() + step - 1) / step;
  }
  if (pairs.empty()) {
    result.refused = fmt::format(
        "the maps do not overlap: none of {} candidate pairs between {} base and {} other places was verified",
        result.candidate_pairs, result.base_places, result.other_places);
    return result;
  }
  result.rival_pairs = consensus.rival_pairs;
  if (!consensus.refused.empty()) {
    result.consistent = consensus.winners;
    result.refused = fmt::format("{} (of {} candidate pairs)", consensus.refused, result.candidate_pairs);
    return result;
  }
  if (result.surveyed_places > 0) add_guided_pairs(base, other, step, config, result, consensus);
  result.consistent = consensus.winners;
  const std::vector<std::size_t>& winners = consensus.winners;
  const std::size_t best = consensus.best;
  const RefinedClouds refined = refine_places(base, other, pairs, winners, pairs[best].T_base_other, config);
  result.T_base_other = refined.T_base_other;
  result.overlap = refined.overlap;
  result.rmse = refined.rmse;
  if (result.overlap < config.min_refined_overlap) {
    result.refused = fmt::format(
        "the maps do not match around the places the pairs agree on: {} consistent pairs, but only {:.0f}% of the "
        "other map's voxels near them lie on the base's after refinement (at least {:.0f}% needed; different places "
        "that look alike?)",
        winners.size(), 100.0 * result.overlap, 100.0 * config.min_refined_overlap);
    return result;
  }
  // Spread of the winning pairs about the result, as the standard error of their mean.
  double sum_t = 0.0, sum_r = 0.0;
  for (const std::size_t i : winners) {
    const Vec3d& x = pairs[i].other_place_world;
    sum_t += (result.T_base_other * x - pairs[i].T_base_other * x).squaredNorm();
    sum_r += std::pow(rotation_angle(result.T_base_other.inverse() * pairs[i].T_base_other), 2);
  }
  const double n = static_cast<double>(winners.size());
  result.sigma_translation = std::sqrt(sum_t / n) / std::sqrt(n);
  result.sigma_rotation = std::sqrt(sum_r / n) / std::sqrt(n);
  // Each other submap with winning pairs re-measured alone, from the whole's result: the joint
  // graph's evidence where the session drifted (the pairs' own transforms come from ICP on
  // 0.5 m clouds: 0.08 m off at the anchors where the refined whole was 0.007 m off).
  std::map<std::size_t, std::size_t> pairs_in_submap;  // other submap index -> winning pairs
  for (const std::size_t i : winners) ++pairs_in_submap[other.places[pairs[i].other_place].submap];
  const std::vector<std::pair<std::size_t, std::size_t>> refined_submaps(pairs_in_submap.begin(), pairs_in_submap.end());
  std::vector<RefinedClouds> submap_results(refined_submaps.size());
  tbb::parallel_for(std::size_t{0}, refined_submaps.size(), [&](std::size_t k) {
    submap_results[k] = refine_places(base, other, pairs, winners, result.T_base_other, config, refined_submaps[k].first);
  });
  for (std::size_t k = 0; k < refined_submaps.size(); ++k) {
    const RefinedClouds& r = submap_results[k];
    if (r.overlap < config.min_refined_overlap) continue;
    const auto [submap, count] = refined_submaps[k];
    result.submap_refinements.push_back({other_submaps[submap].id, r.T_base_other, r.overlap, r.rmse, count});
  }
  result.aligned = true;
  return result;
}

}  // namespace slamvdb::sessions
