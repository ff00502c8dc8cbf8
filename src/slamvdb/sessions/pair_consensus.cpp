#include "slamvdb/sessions/pair_consensus.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <set>

#include "slamvdb/core/error.hpp"

namespace slamvdb::sessions {

void ConsensusConfig::validate() const {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("invalid alignment consensus setting: " + what);
  };
  require(consensus_translation > 0.0 && consensus_rotation > 0.0, "consensus tolerances must be > 0");
  require(min_verified_pairs >= 2, "min verified pairs must be >= 2 (one pair cannot be checked against another)");
  require(ambiguity_ratio > 0.0 && ambiguity_ratio <= 1.0, "ambiguity ratio must be in (0, 1]");
  require(max_ambiguous_place_fraction >= 0.0 && max_ambiguous_place_fraction <= 1.0,
          "max ambiguous place fraction must be in [0, 1]");
}

bool verified_pairs_agree(const VerifiedPair& a, const VerifiedPair& b, const ConsensusConfig& config) {
  if (Eigen::AngleAxisd((a.T_base_other.inverse() * b.T_base_other).linear()).angle() > config.consensus_rotation)
    return false;
  for (const Vec3d& x : {a.other_place_world, b.other_place_world})
    if ((a.T_base_other * x - b.T_base_other * x).norm() > config.consensus_translation) return false;
  return true;
}

PairConsensus find_pair_consensus(const std::vector<VerifiedPair>& pairs, const ConsensusConfig& config) {
  config.validate();
  PairConsensus out;
  if (pairs.empty()) {
    out.refused = "no verified pair";
    return out;
  }
  const auto support_of = [&](std::size_t i, const std::vector<bool>& eligible) {
    std::vector<std::size_t> set;
    for (std::size_t j = 0; j < pairs.size(); ++j)
      if (eligible[j] && verified_pairs_agree(pairs[i], pairs[j], config)) set.push_back(j);
    return set;
  };
  // The pair that most others agree with (ties: the lower RMSE, then the first).
  const std::vector<bool> all(pairs.size(), true);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    std::vector<std::size_t> set = support_of(i, all);
    if (set.size() > out.winners.size() || (set.size() == out.winners.size() && pairs[i].rmse < pairs[out.best].rmse)) {
      out.best = i;
      out.winners = std::move(set);
    }
  }
  std::vector<bool> outside(pairs.size(), true);
  for (const std::size_t i : out.winners) outside[i] = false;
  for (std::size_t i = 0; i < pairs.size(); ++i)
    if (outside[i]) out.rival_pairs = std::max(out.rival_pairs, support_of(i, outside).size());
  std::set<std::size_t> places, elsewhere;
  for (const std::size_t i : out.winners) places.insert(pairs[i].other_place);
  for (std::size_t i = 0; i < pairs.size(); ++i)
    if (outside[i] && places.count(pairs[i].other_place)) elsewhere.insert(pairs[i].other_place);
  out.winner_places = places.size();
  out.ambiguous_places = elsewhere.size();

  if (out.winner_places < config.min_verified_pairs)
    out.refused = fmt::format(
        "too little evidence: the largest consistent set of verified pairs covers {} place(s) of the other map, "
        "{} needed ({} pairs verified)",
        out.winner_places, config.min_verified_pairs, pairs.size());
  else if (out.rival_pairs >= 2 &&
           static_cast<double>(out.rival_pairs) >= config.ambiguity_ratio * static_cast<double>(out.winners.size()))
    out.refused = fmt::format(
        "ambiguous: {} verified pairs agree on one alignment but {} others agree on a different one "
        "(look-alike places?)",
        out.winners.size(), out.rival_pairs);
  else if (static_cast<double>(out.ambiguous_places) >
           config.max_ambiguous_place_fraction * static_cast<double>(out.winner_places))
    out.refused = fmt::format(
        "ambiguous: {} of the {} places of the other map in the winning set verify as well at another alignment "
        "(look-alike places?)",
        out.ambiguous_places, out.winner_places);
  return out;
}

}  // namespace slamvdb::sessions
