#include "slamvdb/sessions/joint_graph.hpp"

#include <fmt/format.h>

#include <set>

#include "slamvdb/core/error.hpp"

namespace slamvdb::sessions {

std::map<int, Pose> correct_other_anchors(const std::vector<SessionSubmap>& other, const SessionAlignment& alignment,
                                          const JointGraphConfig& config) {
  localization::PoseGraph graph;
  graph.add_vertex(Pose::Identity());  // the base's world, fixed
  std::map<int, std::size_t> vertex_of;
  for (std::size_t i = 0; i < other.size(); ++i) {
    vertex_of[other[i].id] = graph.add_vertex(alignment.T_base_other * other[i].T_world_submap);
    if (i == 0) continue;
    const Pose T_prev_this = other[i - 1].T_world_submap.inverse() * other[i].T_world_submap;
    const double d = T_prev_this.translation().norm();
    graph.add_edge({vertex_of[other[i - 1].id], vertex_of[other[i].id], T_prev_this,
                    localization::isotropic_information(
                        config.chain_sigma_translation + config.chain_sigma_translation_per_m * d,
                        config.chain_sigma_rotation + config.chain_sigma_rotation_per_m * d),
                    false});
  }
  const auto vertex_of_submap = [&](int id) {
    const auto it = vertex_of.find(id);
    if (it == vertex_of.end())
      throw Error(fmt::format("joint graph: the alignment names submap {}, which the other map does not have", id));
    return it->second;
  };
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
