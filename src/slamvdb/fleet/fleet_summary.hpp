#pragma once
// Per-submap summaries that let a region query skip submaps without reading them
// (docs/fleet-design.md, "Summaries"): the embedding cap of a submap, a unit centroid and the
// largest angle of any of its embeddings from it. Any non-negative combination of embeddings in a
// cap of radius < 90 degrees lies in the same cap (the cap's cone is convex), so a cell of the
// global index that averages entries of several submaps is bounded by a cap enclosing theirs:
// no cell can score a cosine above cos(max(0, angle(q, centroid) - radius)).
#include <Eigen/Core>
#include <optional>
#include <span>
#include <vector>

#include "slamvdb/map/semantic_layer.hpp"

namespace slamvdb::fleet {

struct EmbeddingCap {
  std::vector<float> centroid;  // unit length
  double radius = 0;            // radians, 0..pi
};

// The cap of a layer's embeddings (zero or non-finite ones, which score nothing, left out);
// nullopt when none is left. Computed on the decoded values, as a reader decodes them.
std::optional<EmbeddingCap> embedding_cap(const SemanticLayer& layer);

// One cap holding every given cap (centred on their centroids' normalised sum); nullopt when the
// list is empty or the centroids cancel out.
std::optional<EmbeddingCap> enclosing_cap(std::span<const EmbeddingCap> caps);

// The largest cosine with the unit query `q` of any non-negative combination of vectors in the
// cap, plus a margin for fp16 storage and fp32 rounding (kCapBoundMargin); 1 when the cap reaches
// 90 degrees or more (its cone is then not convex: no bound).
inline constexpr double kCapBoundMargin = 2e-3;
double cap_cosine_bound(const EmbeddingCap& cap, const Eigen::VectorXf& q);

}  // namespace slamvdb::fleet
