#pragma once
// Transforms between frames as /tf_static and /tf give them (the first of each parent-child pair),
// and the transform between two frames through the tree (edges walked both ways).
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

class TfEdges {
 public:
  // T_parent_child; a pair already known keeps its first transform (the extrinsics are static).
  void add(const std::string& parent, const std::string& child, const Pose& T_parent_child);
  // T_a_b (maps points from b into a) through the tree; nullopt when the frames are not connected.
  std::optional<Pose> find(const std::string& a, const std::string& b) const;
  bool empty() const { return edges_.empty(); }

 private:
  std::map<std::pair<std::string, std::string>, Pose> edges_;
};

}  // namespace slamvdb
