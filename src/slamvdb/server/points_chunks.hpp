#pragma once
// GET /api/points without HTTP: the occupied voxels of a map as compact chunks for a 3D viewer, one
// chunk per (submap, octree node at the asked level of detail). Positions stay in the submap's frame,
// quantised per chunk, and each chunk carries its submap's T_world_submap: a loop correction moves
// a chunk as a whole (the viewer changes one matrix), nothing is re-tiled. Each point carries one
// byte: its class (against the server's query set) or its score against a question, quantised.
// Embeddings never leave the server. The byte layout is in docs/openapi.yaml (/api/points) and
// docs/serve-design.md; encode_point_chunks is its one writer.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/query/query_classifier.hpp"
#include "slamvdb/query/query_region.hpp"
#include "slamvdb/query/query_set.hpp"

namespace slamvdb {

// An octree node (one chunk) is kPointsNodeVoxels voxels on a side at every level of detail; level L
// draws one point per 2^L x 2^L x 2^L voxels that holds an occupied voxel.
inline constexpr int kPointsNodeBits = 8;
inline constexpr int kPointsNodeVoxels = 1 << kPointsNodeBits;
inline constexpr int kPointsMaxLod = kPointsNodeBits;
// The viewer's point budget (issue 21: about 2 M points): an answer holds at most this many points
// unless the request asks for fewer; a region holding more at the asked level is refused (413).
inline constexpr std::size_t kPointsDefaultLimit = 2'000'000;
inline constexpr std::size_t kPointsMaxLimit = 8'000'000;
inline constexpr uint8_t kPointNoValue = 255;  // no class / no score (a voxel without semantics)

struct PointsRequest {
  std::optional<QueryRegion> region;  // world frame; a point is in it when its centre is; null: the whole map
  int lod = 0;                        // 0..kPointsMaxLod
  std::size_t limit = kPointsDefaultLimit;
  std::optional<int> submap;          // one submap only (live mode: the page fetches a new submap's chunks)
};

// What each point's byte says: the class of its index cell against `queries` (classify_map's class,
// as `slamvdb classify` writes it), or, with `query`, the cell's cosine similarity to it. Neither:
// every value is kPointNoValue.
struct PointValueSource {
  const QuerySet* queries = nullptr;
  ClassifyOptions classify{};
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;
  std::optional<Eigen::VectorXf> query;  // the composite query vector (map dimension)
};

struct PointChunk {
  int submap_id = 0;
  int lod = 0;
  Pose T_world_submap = Pose::Identity();
  Vec3f origin_submap = Vec3f::Zero();  // the node's corner, submap frame (m)
  float step = 0.f;                     // metres per quantum: position_submap = origin + step * q
  std::vector<uint16_t> positions;      // q, 3 per point
  std::vector<uint8_t> values;          // 1 per point: class index or quantised score, 255 none
};

struct PointChunks {
  enum class Values { kNone, kClass, kScore } values = Values::kNone;
  std::vector<PointChunk> chunks;  // by submap id, then node key order
  std::size_t points = 0;
  // kScore: value v (0..254) stands for score_lo + (score_hi - score_lo) * v / 254.
  float score_lo = 0.f, score_hi = 0.f;
  double voxel_size = 0.0;
};

// Thrown before any value is computed when the region holds more points than request.limit at the
// asked level of detail (the server answers 413 naming the count).
class PointsOverBudget : public Error {
 public:
  PointsOverBudget(std::size_t points, std::size_t limit, int lod);
  std::size_t points() const { return points_; }

 private:
  std::size_t points_;
};

// The occupied voxels (occupancy >= the occupied threshold) of every submap in memory, one point per
// occupied 2^lod group, grouped by (submap, node). A group's value: the class most of its voxels'
// index cells have (ties: the lower class index), or the highest score among them. Throws
// PointsOverBudget, and Error for a query vector of the wrong dimension or a query set of another space.
PointChunks collect_point_chunks(const SemanticMap& map, const PointsRequest& request, const PointValueSource& values);

// The bytes of an answer (little-endian): header "SVPT", u16 version 1, u16 flags (bit 0: values are
// scores), u32 chunk count, u32 meta length, `meta` as UTF-8 JSON padded with spaces to 4 bytes, then
// each chunk: i32 submap id, u8 lod, u8[3] 0, f32[12] T_world_submap rows 0..2 row-major, f32[3]
// origin, f32 step, u32 point count n, u16[3n] q, u8[n] values, zero padding to 4 bytes.
std::string encode_point_chunks(const PointChunks& chunks, const nlohmann::json& meta);

}  // namespace slamvdb
