#include "slamvdb/sessions/map_merge.hpp"

#include <fmt/format.h>

#include <map>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/sessions/map_alignment.hpp"

namespace slamvdb::sessions {

std::string merge_incompatibility(const MapParams& first_params, const MapInfo& first_info, const MapParams& params,
                                  const MapInfo& info) {
  std::string out = map_incompatibility(first_params, first_info, params, info);
  if (!out.empty()) return out;
  const OccupancyParams &a = first_params.occupancy, &b = params.occupancy;
  const auto differ = [&](const char* what, double x, double y) {
    if (out.empty() && x != y) out = fmt::format("the maps have different occupancy settings: {} {} and {}", what, x, y);
  };
  differ("log-odds hit", a.log_odds_hit, b.log_odds_hit);
  differ("log-odds miss", a.log_odds_miss, b.log_odds_miss);
  differ("clamp min", a.clamp_min, b.clamp_min);
  differ("clamp max", a.clamp_max, b.clamp_max);
  differ("occupied threshold", a.occupied_threshold, b.occupied_threshold);
  return out;
}

MapContents& MapContents::operator+=(const MapContents& o) {
  sessions += o.sessions, submaps += o.submaps, occupied_voxels += o.occupied_voxels;
  semantic_voxels += o.semantic_voxels, observations += o.observations;
  return *this;
}

MapContents map_contents(const SemanticMap& map) {
  MapContents c;
  c.sessions = map.info().sessions.empty() ? 1 : map.info().sessions.size();
  c.submaps = map.num_submaps();
  c.occupied_voxels = map.num_occupied_voxels();
  c.semantic_voxels = map.num_semantic_voxels();
  for (const SubmapInfo& info : map.submaps())
    map.read_submap(info.id, [&](const Submap& s) {
      const SemanticLayer& layer = s.voxels().semantics();
      layer.for_each([&](SemanticLayer::Handle h) { c.observations += layer.count_of(h); });
    });
  return c;
}

SemanticMap merge_session_maps(std::vector<SemanticMap>& inputs, const std::vector<std::string>& labels,
                               MapMergeReport& report, const OverlapMergeOptions& overlap) {
  if (inputs.size() < 2 || labels.size() != inputs.size())
    throw Error(fmt::format("merging needs two maps or more, each with a label ({} maps, {} labels)", inputs.size(),
                            labels.size()));
  for (std::size_t i = 1; i < inputs.size(); ++i) {
    const std::string incompatible =
        merge_incompatibility(inputs[0].params(), inputs[0].info(), inputs[i].params(), inputs[i].info());
    if (!incompatible.empty())
      throw Error(fmt::format("cannot merge {} with {}: {}", labels[i], labels[0], incompatible));
  }
  report = {};
  MapInfo info = inputs[0].info();
  info.sessions.clear();
  std::vector<std::map<int, int>> new_session_ids(inputs.size());  // per input: old id -> merged id
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    report.inputs.push_back(map_contents(inputs[i]));
    // The input's sessions, renumbered in input order; an input that lists none is one session.
    std::vector<SessionInfo> sessions = inputs[i].info().sessions;
    if (sessions.empty()) sessions.push_back({0, labels[i], inputs[i].info().source, "", {}});
    for (SessionInfo s : sessions) {
      new_session_ids[i][s.id] = static_cast<int>(info.sessions.size());
      s.id = static_cast<int>(info.sessions.size());
      info.sessions.push_back(std::move(s));
    }
    for (const SubmapInfo& s : inputs[i].submaps()) {  // checked before any submap moves
      if (!s.finished)
        throw Error(fmt::format("cannot merge {}: its submap {} is still being written", labels[i], s.id));
      if (new_session_ids[i].count(s.session) == 0)
        throw Error(fmt::format("cannot merge {}: its submap {} belongs to session {}, which it does not list",
                                labels[i], s.id, s.session));
    }
  }
  std::vector<std::pair<SubmapInfo, VoxelMap>> submaps;  // new ids: input order, then the input's id order
  for (std::size_t i = 0; i < inputs.size(); ++i)
    for (auto& [submap, voxels] : inputs[i].take_finished_submaps()) {  // by id
      submap.id = static_cast<int>(submaps.size());
      submap.session = new_session_ids[i].at(submap.session);
      // Its voxels' last-observed sessions follow (an input listing no session tags them 0).
      voxels.semantics().renumber_sessions(new_session_ids[i]);
      submaps.emplace_back(std::move(submap), std::move(voxels));
    }
  // Which drive is newer comes from the sessions' time ranges: the union of their submaps' (as a
  // saved file has them), also for maps that were never saved; a session without submaps keeps its own.
  std::map<int, TimeRange> of_submaps;
  for (const auto& [submap, voxels] : submaps) of_submaps[submap.session].extend(submap.time_range);
  for (SessionInfo& session : info.sessions)
    if (of_submaps.contains(session.id)) session.time = of_submaps.at(session.id);
  report.absorbed = merge_overlapping_sessions(submaps, overlap, SessionOrder(info.sessions));
  SemanticMap merged(inputs[0].params(), info);
  for (auto& [submap, voxels] : submaps) merged.add_finished_submap(submap, std::move(voxels));
  report.merged = map_contents(merged);
  // Nothing may be lost on the way: the merged map holds what the inputs held, count for count,
  // less what each merge of overlapping submaps combined (a place in both is one voxel now) or
  // dropped (and reported).
  MapContents expected;
  for (const MapContents& c : report.inputs) expected += c;
  for (const SubmapAbsorption& a : report.absorbed) {
    --expected.submaps;
    expected.occupied_voxels -= static_cast<std::size_t>(a.occupied_voxels_removed);  // wraps back if negative
    expected.semantic_voxels -= a.semantic_voxels_removed;
    expected.observations -= a.observations_dropped_free + a.observations_clipped;
  }
  if (!(report.merged == expected))
    throw Error(fmt::format("merging lost content ({} submaps, {} observations expected; {} and {} out)",
                            expected.submaps, expected.observations, report.merged.submaps,
                            report.merged.observations));
  return merged;
}

}  // namespace slamvdb::sessions
