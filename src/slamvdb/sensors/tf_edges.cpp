#include "slamvdb/sensors/tf_edges.hpp"

#include <deque>
#include <set>

namespace slamvdb {

void TfEdges::add(const std::string& parent, const std::string& child, const Pose& T_parent_child) {
  edges_.emplace(std::make_pair(parent, child), T_parent_child);
}

std::optional<Pose> TfEdges::find(const std::string& a, const std::string& b) const {
  // Breadth first from a; T_a_x known for every frame x reached.
  std::map<std::string, Pose> reached{{a, Pose::Identity()}};
  std::deque<std::string> todo{a};
  while (!todo.empty()) {
    const std::string x = todo.front();
    todo.pop_front();
    if (x == b) return reached.at(x);
    const Pose T_a_x = reached.at(x);
    for (const auto& [edge, T_parent_child] : edges_) {
      const auto& [parent, child] = edge;
      if (parent == x && !reached.count(child)) {
        reached.emplace(child, T_a_x * T_parent_child);
        todo.push_back(child);
      } else if (child == x && !reached.count(parent)) {
        reached.emplace(parent, T_a_x * T_parent_child.inverse());
        todo.push_back(parent);
      }
    }
  }
  return std::nullopt;
}

}  // namespace slamvdb
