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
#include "slamvdb/sessions/place_pair_verification.hpp"
#include "slamvdb/sessions/session_refinement.hpp"

namespace slamvdb::sessions {

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
  // The whole's ICP first, then the base's surface planes near the other session's points where
  // it puts them, fitted once for every refinement (session_refinement.hpp).
  std::set<std::size_t> base_places, other_places;
  winning_places(other, pairs, winners, std::nullopt, base_places, other_places);
  RefinementBase refinement_base(base, base_places, config);
  const RefinementSource whole = refinement_source(other, other_places, config);
  const Pose T_whole_icp = refinement_base.icp(whole, pairs[best].T_base_other);
  if (config.surface_refinement) refinement_base.add_planes_near(whole, T_whole_icp);
  const RefinedClouds refined = refinement_base.finish(whole, T_whole_icp);
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
    std::set<std::size_t> submap_base_places, submap_places;
    winning_places(other, pairs, winners, refined_submaps[k].first, submap_base_places, submap_places);
    RefinementBase own(base, submap_base_places, config);
    own.use_planes_of(refinement_base);
    submap_results[k] =
        own.refine(refinement_source(other, submap_places, config, refined_submaps[k].first), result.T_base_other,
                               /*from_refined=*/true);
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
