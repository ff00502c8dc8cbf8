#include "slamvdb/sessions/joint_graph.hpp"

#include <fmt/format.h>

#include <set>

#include "slamvdb/core/error.hpp"

namespace slamvdb::sessions {
namespace {

// One vertex per submap of a session (anchors moved by T_base_session), chained in id order by
// their stored relative poses with the odometry model's information. Returns id -> vertex.
std::map<int, std::size_t> add_session_chain(localization::PoseGraph& graph, const std::vector<SessionSubmap>& submaps,
                                             const Pose& T_base_session, const JointGraphConfig& config) {
  std::map<int, std::size_t> vertex_of;
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    vertex_of[submaps[i].id] = graph.add_vertex(T_base_session * submaps[i].T_world_submap);
    if (i == 0) continue;
    const Pose T_prev_this = submaps[i - 1].T_world_submap.inverse() * submaps[i].T_world_submap;
    const double d = T_prev_this.translation().norm();
    graph.add_edge({vertex_of[submaps[i - 1].id], vertex_of[submaps[i].id], T_prev_this,
                    localization::isotropic_information(
                        config.chain_sigma_translation + config.chain_sigma_translation_per_m * d,
                        config.chain_sigma_rotation + config.chain_sigma_rotation_per_m * d),
                    false});
  }
  return vertex_of;
}

std::size_t vertex_of_submap(const std::map<int, std::size_t>& vertex_of, int id, const char* session) {
  const auto it = vertex_of.find(id);
  if (it == vertex_of.end())
    throw Error(fmt::format("joint graph: the alignment names submap {}, which the {} map does not have", id, session));
  return it->second;
}

const SessionSubmap& submap_with_id(const std::vector<SessionSubmap>& submaps, int id) {
  for (const SessionSubmap& s : submaps)
    if (s.id == id) return s;
  throw Error(fmt::format("joint graph: no submap {}", id));
}

}  // namespace

JointCorrection correct_both_anchors(const std::vector<SessionSubmap>& base, const std::vector<SessionSubmap>& other,
                                     const SessionAlignment& alignment, const JointGraphConfig& config) {
  if (base.empty()) throw Error("joint graph: the base map has no submaps");
  localization::PoseGraph graph;
  const std::map<int, std::size_t> base_vertex = add_session_chain(graph, base, Pose::Identity(), config);
  const std::map<int, std::size_t> other_vertex = add_session_chain(graph, other, alignment.T_base_other, config);
  // T_bsubmap_osubmap from a world-to-world transform measured against base submap b.
  const auto relative_edge = [&](int b, int o, const Pose& T_base_other, double sigma_t, double sigma_r) {
    const Pose T_bsubmap_osubmap = submap_with_id(base, b).T_world_submap.inverse() * T_base_other *
                                   submap_with_id(other, o).T_world_submap;
    graph.add_edge({vertex_of_submap(base_vertex, b, "base"), vertex_of_submap(other_vertex, o, "other"),
                    T_bsubmap_osubmap, localization::isotropic_information(sigma_t, sigma_r), true});
  };
  // Which base submap each other submap's winning pairs were measured against most (ties: lower id).
  std::map<int, std::map<int, std::size_t>> pairs_with;  // other id -> base id -> pairs
  for (const std::size_t w : alignment.consistent) {
    const VerifiedPair& pair = alignment.verified.at(w);
    ++pairs_with[pair.other_submap_id][pair.base_submap_id];
  }
  std::map<int, int> refined_against;  // other id -> the base submap its refinement is tied to
  if (config.use_submap_refinements) {
    for (const SubmapRefinement& r : alignment.submap_refinements) {
      const auto it = pairs_with.find(r.other_submap_id);
      if (it == pairs_with.end()) continue;  // a refinement comes from winning pairs; none: no base submap to tie to
      int best = it->second.begin()->first;
      for (const auto& [b, n] : it->second)
        if (n > it->second.at(best)) best = b;
      relative_edge(best, r.other_submap_id, r.T_base_other, config.refined_sigma_translation,
                    config.refined_sigma_rotation);
      refined_against[r.other_submap_id] = best;
    }
  }
  // The pairs tie each other submap to every other base submap it was seen from: those links are
  // what carries the other session's shape into a drifted base (the refinement ties one only).
  for (const std::size_t w : alignment.consistent) {
    const VerifiedPair& pair = alignment.verified.at(w);
    const auto it = refined_against.find(pair.other_submap_id);
    if (it != refined_against.end() && it->second == pair.base_submap_id) continue;  // measured better, refined
    relative_edge(pair.base_submap_id, pair.other_submap_id, pair.T_base_other, config.pair_sigma_translation,
                  config.pair_sigma_rotation);
  }
  graph.optimize(config.graph);
  JointCorrection out;
  for (const auto& [id, vertex] : base_vertex) out.base[id] = graph.pose(vertex);
  for (const auto& [id, vertex] : other_vertex) out.other[id] = graph.pose(vertex);
  return out;
}

std::map<int, Pose> correct_other_anchors(const std::vector<SessionSubmap>& other, const SessionAlignment& alignment,
                                          const JointGraphConfig& config) {
  localization::PoseGraph graph;
  graph.add_vertex(Pose::Identity());  // the base's world, fixed
  // Vertices 1..n: other[vertex - 1].
  const std::map<int, std::size_t> vertex_of = add_session_chain(graph, other, alignment.T_base_other, config);
  const auto vertex_of_submap = [&](int id) { return sessions::vertex_of_submap(vertex_of, id, "other"); };
  std::set<int> refined;
  if (config.use_submap_refinements) {
    for (const SubmapRefinement& r : alignment.submap_refinements) {
      const std::size_t vertex = vertex_of_submap(r.other_submap_id);
      refined.insert(r.other_submap_id);
      graph.add_edge({0, vertex, r.T_base_other * other[vertex - 1].T_world_submap,
                      localization::isotropic_information(config.refined_sigma_translation,
                                                          config.refined_sigma_rotation),
                      true});
    }
  }
  for (const std::size_t w : alignment.consistent) {
    const VerifiedPair& pair = alignment.verified.at(w);
    const std::size_t vertex = vertex_of_submap(pair.other_submap_id);
    if (refined.count(pair.other_submap_id) != 0) continue;  // measured better by its refinement
    graph.add_edge({0, vertex, pair.T_base_other * other[vertex - 1].T_world_submap,
                    localization::isotropic_information(config.pair_sigma_translation, config.pair_sigma_rotation),
                    true});
  }
  graph.optimize(config.graph);
  std::map<int, Pose> out;
  for (const auto& [id, vertex] : vertex_of) out[id] = graph.pose(vertex);
  return out;
}

}  // namespace slamvdb::sessions
