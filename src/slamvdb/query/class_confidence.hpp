#pragma once
// How sure the map is of a voxel's class at query time (issue 22, first step).
#include <cstdint>

#include "slamvdb/query/query_classifier.hpp"

namespace slamvdb {

// How sure the map is of a voxel's class, at query time (0..1): the margin between the best and
// the runner-up class's cosine (how clearly the fused embedding points at one class; +inf, one
// choosable class, counts as 1), damped for voxels seen in few views: margin x n / (n + 2) for n
// fused observations. 0 without a class. Used to rank voxels (eval's accuracy-coverage table).
inline float class_confidence(const QueryMatch& m, uint32_t observations) {
  if (m.class_index == kNoClass) return 0.f;
  const float margin = m.margin > 1.f ? 1.f : (m.margin > 0.f ? m.margin : 0.f);
  const float n = static_cast<float>(observations);
  return margin * n / (n + 2.f);
}

}  // namespace slamvdb
