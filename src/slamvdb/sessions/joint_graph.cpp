#include "slamvdb/sessions/joint_graph.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb::sessions {

std::map<int, Pose> correct_other_anchors(const std::vector<SessionSubmap>& other,
                                          const std::vector<VerifiedPair>& pairs,
                                          const std::vector<std::size_t>& winners, const Pose& T_base_other,
                                          const JointGraphConfig& config) {
  localization::PoseGraph graph;
  graph.add_vertex(Pose::Identity());  // the base's world, fixed
  std::map<int, std::size_t> vertex_of;
  for (std::size_t i = 0; i < other.size(); ++i) {
    vertex_of[other[i].id] = graph.add_vertex(T_base_other * other[i].T_world_submap);
    if (i == 0) continue;
    const Pose T_prev_this = other[i - 1].T_world_submap.inverse() * other[i].T_world_submap;
    const double d = T_prev_this.translation().norm();
    graph.add_edge({vertex_of[other[i - 1].id], vertex_of[other[i].id], T_prev_this,
                    localization::isotropic_information(
                        config.chain_sigma_translation + config.chain_sigma_translation_per_m * d,
                        config.chain_sigma_rotation + config.chain_sigma_rotation_per_m * d),
                    false});
  }
  for (const std::size_t w : winners) {
    const VerifiedPair& pair = pairs.at(w);
    const auto it = vertex_of.find(pair.other_submap_id);
    if (it == vertex_of.end())
      throw Error(fmt::format("joint graph: a verified pair names submap {}, which the other map does not have",
                              pair.other_submap_id));
    const Pose& T_other_submap = other[it->second - 1].T_world_submap;
    graph.add_edge({0, it->second, pair.T_base_other * T_other_submap,
                    localization::isotropic_information(config.pair_sigma_translation, config.pair_sigma_rotation),
                    true});
  }
  graph.optimize(config.graph);
  std::map<int, Pose> out;
  for (const auto& [id, vertex] : vertex_of) out[id] = graph.pose(vertex);
  return out;
}

}  // namespace slamvdb::sessions
