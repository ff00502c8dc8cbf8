#pragma once
// How sure the map is of a voxel's class at query time (issue 22, beyond the paper).
#include <cstdint>

#include "slamvdb/map/semantic_layer.hpp"
#include "slamvdb/query/query_classifier.hpp"

namespace slamvdb {

// The margin term alone (0..1): the margin between the best and the runner-up class's cosine (how
// clearly the fused embedding points at one class; +inf, one choosable class, counts as 1), damped
// for voxels seen in few views: margin x n / (n + 2) for n fused observations. 0 without a class.
inline float class_confidence(const QueryMatch& m, uint32_t observations) {
  if (m.class_index == kNoClass) return 0.f;
  const float margin = m.margin > 1.f ? 1.f : (m.margin > 0.f ? m.margin : 0.f);
  const float n = static_cast<float>(observations);
  return margin * n / (n + 2.f);
}

// The median spread S/W of the voxels of the honest drive (eval/honest_accuracy_test.cpp,
// realistic SIMULATED encoder, 64-d, paper's rule: 0.169; quality weighting 0.161): the scale of
// the optional spread factor below.
inline constexpr float kMedianSpread = 0.17f;

// A voxel's confidence (0..1), what classify, query, eval and the Python API report:
// class_confidence, times 1 / (1 + (S/W) / spread_scale) when spread_scale > 0, so that a voxel
// whose views disagreed would count less sure than one of equal margin whose views agreed. The
// spread factor is off by default (spread_scale 0): on the honest drive it made the ranking worse
// (most confident half 86.0 % accurate with it at kMedianSpread vs 88.4 % without, paper's rule;
// README "Honest accuracy"): a voxel whose views disagree is mostly one whose fused embedding
// already sits between classes, which the margin sees. Statistics not known (maps saved before
// format 3): the factor is 1.
inline float voxel_confidence(const QueryMatch& m, uint32_t observations, VoxelStatistics stats,
                              float spread_scale = 0.f) {
  const float c = class_confidence(m, observations);
  if (!(spread_scale > 0.f) || !stats.known() || !(stats.weight > 0.f)) return c;
  const float spread = stats.spread / stats.weight;
  return spread > 0.f ? c / (1.f + spread / spread_scale) : c;
}

}  // namespace slamvdb
