#include "slamvdb/server/points_chunks.hpp"

#include <absl/container/flat_hash_map.h>
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>

#include "slamvdb/query/map_query.hpp"
#include "slamvdb/server/map_service.hpp"

namespace slamvdb {

namespace points_chunks_detail {

// One occupied voxel on its way into a chunk: its node, its group at the asked level (both in the
// submap frame) and the cell of the global index its world centre falls in (where its value is).
struct PendingVoxel {
  VoxelKey node, group;
  IndexCellKey cell;
};

bool pending_before(const PendingVoxel& a, const PendingVoxel& b) {
  if (a.node != b.node) return a.node < b.node;
  if (a.group != b.group) return a.group < b.group;
  return a.cell < b.cell;
}

VoxelKey shifted(const VoxelKey& k, int bits) { return {k.x() >> bits, k.y() >> bits, k.z() >> bits}; }

// The region the values are computed for: the request's box grown by a group and a cell (a group's
// centre may be inside while one of its voxels' cells is not); null: the whole map.
std::optional<QueryRegion> value_region(const PointsRequest& request, double margin) {
  if (!request.region) return std::nullopt;
  Eigen::AlignedBox3d box = request.region->bounds();
  if (!box.min().allFinite() || !box.max().allFinite()) return std::nullopt;
  box.min().array() -= margin;
  box.max().array() += margin;
  QueryRegion r;
  r.box = box;
  return r;
}

void put_bytes(std::string& out, const void* data, std::size_t n) { out.append(static_cast<const char*>(data), n); }
template <class T>
void put(std::string& out, T value) {  // little-endian hosts only (x86-64, arm64): checked below
  put_bytes(out, &value, sizeof value);
}
static_assert(std::endian::native == std::endian::little, "the /api/points encoder writes host order");

void pad_to_4(std::string& out, char fill) {
  while (out.size() % 4 != 0) out.push_back(fill);
}

}  // namespace points_chunks_detail

PointsOverBudget::PointsOverBudget(std::size_t points, std::size_t limit, int lod)
    : Error(fmt::format("the region holds {} points at lod {}, over the limit of {} (ask a coarser lod, a smaller "
                        "bbox, or a larger limit up to {})",
                        points, lod, limit, kPointsMaxLimit)),
      points_(points) {}

PointChunks collect_point_chunks(const SemanticMap& map, const PointsRequest& request, const PointValueSource& source) {
  using namespace points_chunks_detail;
  if (request.lod < 0 || request.lod > kPointsMaxLod) throw Error(fmt::format("lod {} is not in 0..{}", request.lod, kPointsMaxLod));
  PointChunks out;
  const double voxel = map.params().occupancy.voxel_size;
  const double inv_cell = 1.0 / map.params().index_cell();
  const double group_size = voxel * static_cast<double>(1 << request.lod);
  out.voxel_size = voxel;

  // 1. The occupied voxels whose group centre lies in the region, per submap (its pose read with its voxels).
  struct SubmapVoxels {
    int id;
    Pose T_world_submap;
    std::vector<PendingVoxel> voxels;
  };
  std::vector<SubmapVoxels> submaps;
  std::size_t points = 0;
  for (const SubmapInfo& info : map.submaps()) {
    if (request.submap && info.id != *request.submap) continue;
    SubmapVoxels s{info.id, info.T_world_submap, {}};
    try {
      map.read_submap(info.id, [&](const Submap& submap) {
        s.T_world_submap = submap.T_world_submap();
        submap.voxels().occupancy().for_each_occupied([&](const VoxelKey& k, float) {
          const VoxelKey group = shifted(k, request.lod);
          const Vec3d group_world = s.T_world_submap * ((group.cast<double>().array() + 0.5).matrix() * group_size);
          if (request.region && !request.region->contains(group_world)) return;
          const Vec3d centre_world = s.T_world_submap * center_of_key(k, voxel);
          s.voxels.push_back({shifted(k, kPointsNodeBits), group, key_of_point<IndexCellKey>(centre_world, inv_cell)});
        });
      });
    } catch (const Error&) {
      continue;  // merged away since submaps() was read (a live map): its voxels are in the target now
    }
    std::sort(s.voxels.begin(), s.voxels.end(), pending_before);
    for (std::size_t i = 0; i < s.voxels.size(); ++i)
      points += i == 0 || s.voxels[i].group != s.voxels[i - 1].group;
    if (!s.voxels.empty()) submaps.push_back(std::move(s));
  }
  if (points > request.limit) throw PointsOverBudget(points, request.limit, request.lod);
  out.points = points;

  // 2. The value of every index cell the points need, by the library's own questions (the CLI's).
  const std::optional<QueryRegion> region = value_region(request, group_size + 1.0 / inv_cell);
  absl::flat_hash_map<IndexCellKey, float> cell_values;
  if (source.query) {
    out.values = PointChunks::Values::kScore;
    SearchOptions search;
    search.region = region;
    search.deadline = source.classify.deadline;  // the answer's time budget (serve --time-budget)
    const auto q = std::span<const float>(source.query->data(), static_cast<std::size_t>(source.query->size()));
    for (const ScoredCell& c : similarity_search(map, q, search)) cell_values[c.cell] = c.score;
  } else if (source.queries) {
    out.values = PointChunks::Values::kClass;
    const std::vector<ClassifiedCell> cells =
        region ? classify_region(map, *source.queries, *region, source.classify, source.model_check)
               : classify_map(map, *source.queries, source.classify, source.model_check);
    for (const ClassifiedCell& c : cells)
      if (c.match.class_index != kNoClass) cell_values[c.cell] = static_cast<float>(c.match.class_index);
  }

  // 3. Chunks: one per (submap, node); a group's value from its voxels' cells.
  const int groups_per_node_bits = kPointsNodeBits - request.lod;
  std::vector<float> scores;  // per point, for the quantisation range (kScore)
  std::vector<int> class_votes(source.queries ? static_cast<std::size_t>(source.queries->size()) : 0);
  for (const SubmapVoxels& s : submaps) {
    for (std::size_t begin = 0; begin < s.voxels.size();) {
      const VoxelKey node = s.voxels[begin].node;
      PointChunk chunk;
      chunk.submap_id = s.id;
      chunk.lod = request.lod;
      chunk.T_world_submap = s.T_world_submap;
      chunk.origin_submap = (node.cast<double>() * (kPointsNodeVoxels * voxel)).cast<float>();
      chunk.step = static_cast<float>(group_size / 2);
      std::size_t i = begin;
      while (i < s.voxels.size() && s.voxels[i].node == node) {
        const VoxelKey group = s.voxels[i].group;
        for (int a = 0; a < 3; ++a)
          chunk.positions.push_back(static_cast<uint16_t>(2 * (group[a] - (node[a] << groups_per_node_bits)) + 1));
        std::fill(class_votes.begin(), class_votes.end(), 0);
        float best_score = -std::numeric_limits<float>::infinity();
        bool any = false;
        for (; i < s.voxels.size() && s.voxels[i].node == node && s.voxels[i].group == group; ++i) {
          if (i > 0 && s.voxels[i].cell == s.voxels[i - 1].cell && s.voxels[i].group == s.voxels[i - 1].group)
            continue;  // two voxels of a group in one cell (a moved submap) vote once
          const auto found = cell_values.find(s.voxels[i].cell);
          if (found == cell_values.end()) continue;
          any = true;
          if (out.values == PointChunks::Values::kClass) ++class_votes[static_cast<std::size_t>(found->second)];
          best_score = std::max(best_score, found->second);
        }
        uint8_t value = kPointNoValue;
        if (any && out.values == PointChunks::Values::kClass)
          value = static_cast<uint8_t>(std::max_element(class_votes.begin(), class_votes.end()) - class_votes.begin());
        if (out.values == PointChunks::Values::kScore) scores.push_back(any ? best_score : std::nanf(""));
        chunk.values.push_back(value);
      }
      out.chunks.push_back(std::move(chunk));
      begin = i;
    }
  }
  if (out.values == PointChunks::Values::kScore) {  // 0..254 over the answer's own range
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (const float v : scores)
      if (!std::isnan(v)) lo = std::min(lo, v), hi = std::max(hi, v);
    if (lo > hi) lo = hi = 0.f;
    out.score_lo = lo, out.score_hi = hi;
    std::size_t k = 0;
    for (PointChunk& chunk : out.chunks)
      for (uint8_t& value : chunk.values) {
        const float v = scores[k++];
        value = std::isnan(v) ? kPointNoValue
                              : static_cast<uint8_t>(hi > lo ? std::lround((v - lo) / (hi - lo) * 254.f) : 254);
      }
  }
  return out;
}

std::string encode_point_chunks(const PointChunks& chunks, const nlohmann::json& meta) {
  using namespace points_chunks_detail;
  std::string out = "SVPT";
  put<uint16_t>(out, 1);
  put<uint16_t>(out, chunks.values == PointChunks::Values::kScore ? 1 : 0);
  put<uint32_t>(out, static_cast<uint32_t>(chunks.chunks.size()));
  std::string meta_text = meta.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  while (meta_text.size() % 4 != 0) meta_text.push_back(' ');
  put<uint32_t>(out, static_cast<uint32_t>(meta_text.size()));
  out += meta_text;
  for (const PointChunk& c : chunks.chunks) {
    put<int32_t>(out, c.submap_id);
    put<uint8_t>(out, static_cast<uint8_t>(c.lod));
    put_bytes(out, "\0\0\0", 3);
    const Eigen::Matrix4d T = c.T_world_submap.matrix();
    for (int r = 0; r < 3; ++r)
      for (int col = 0; col < 4; ++col) put<float>(out, static_cast<float>(T(r, col)));
    for (int a = 0; a < 3; ++a) put<float>(out, c.origin_submap[a]);
    put<float>(out, c.step);
    put<uint32_t>(out, static_cast<uint32_t>(c.values.size()));
    put_bytes(out, c.positions.data(), c.positions.size() * sizeof(uint16_t));
    put_bytes(out, c.values.data(), c.values.size());
    pad_to_4(out, '\0');
  }
  return out;
}

// SemanticMapService's /api/points (map_service.hpp): the map in memory, read as every reader does.
PointChunks SemanticMapService::points(const PointsRequest& request, const PointValueSource& values) const {
  return collect_point_chunks(*map_, request, values);
}

}  // namespace slamvdb
