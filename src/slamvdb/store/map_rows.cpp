// Writing and reading the rows of one submap, with every value checked for meaning on the way in.
#include "slamvdb/store/map_rows.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "slamvdb/core/half.hpp"

namespace slamvdb::store {
namespace {

static_assert(std::endian::native == std::endian::little, "map blobs hold host-order numbers, which must be LE");

constexpr std::size_t kBlockBytes = kBlockVoxels * sizeof(float);
// Block keys are shifted by 3 bits into voxel keys, which stay within the grid extent (keys.hpp).
constexpr int64_t kMaxBlockCoordinate = static_cast<int64_t>(kMaxGridCoordinate) >> kBlockBits;

int64_t submap_crc(const SubmapSummary& s, std::span<const std::byte> pose, int version) {
  Crc crc;
  crc.add(int64_t{s.info.id}).add(pose);
  if (version >= 2) {
    crc.add_real(s.info.time_range.empty() ? 0.0 : s.info.time_range.begin);
    crc.add_real(s.info.time_range.empty() ? 0.0 : s.info.time_range.end);
    crc.add_real(s.info.path_length);
  }
  return crc.add(static_cast<int64_t>(s.blocks))
      .add(static_cast<int64_t>(s.known_voxels))
      .add(static_cast<int64_t>(s.occupied_voxels))
      .add(static_cast<int64_t>(s.semantic_voxels))
      .value();
}

void check_rigid_pose(int id, const Eigen::Matrix4d& m) {
  if (!m.allFinite()) throw Error(fmt::format("submap {} has a non-finite pose", id));
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || std::abs(R.determinant() - 1) > 1e-6 ||
      !m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1)))
    throw Error(fmt::format("submap {} has a pose that is not a rigid transform", id));
  if (m.topRightCorner<3, 1>().cwiseAbs().maxCoeff() > 1e9)
    throw Error(fmt::format("submap {} has a pose {:.3g} m away, outside any map", id, m.topRightCorner<3, 1>().norm()));
}

// True when every stored value is finite (fp16: exponent not all ones; fp32 likewise).
bool embeddings_finite(const std::byte* data, std::size_t values, EmbeddingPrecision precision) {
  unsigned bad = 0;  // branch-free, so that it vectorises
  if (precision == EmbeddingPrecision::kFloat16) {
    for (std::size_t i = 0; i < values; ++i) {
      uint16_t h;
      std::memcpy(&h, data + 2 * i, 2);
      bad |= (h & 0x7c00u) == 0x7c00u;
    }
  } else {
    for (std::size_t i = 0; i < values; ++i) {
      uint32_t f;
      std::memcpy(&f, data + 4 * i, 4);
      bad |= (f & 0x7f800000u) == 0x7f800000u;
    }
  }
  return !bad;
}

// Occupancy blocks are compressed with raw deflate (version 2): the zlib wrapper's Adler-32 would
// check what the row's CRC already checks, at 7% of the load time. The streams are reused: a
// fresh deflate state allocates 256 KB per block.
class BlockCodec {
 public:
  BlockCodec() {
    if (deflateInit2(&def_, Z_BEST_SPEED, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK ||
        inflateInit2(&inf_, -15) != Z_OK)
      throw Error("zlib failed to initialise");
  }
  ~BlockCodec() {
    deflateEnd(&def_);
    inflateEnd(&inf_);
  }
  BlockCodec(const BlockCodec&) = delete;
  BlockCodec& operator=(const BlockCodec&) = delete;

  std::span<const std::byte> compress(const float* log_odds) {
    out_.resize(deflateBound(&def_, kBlockBytes));
    deflateReset(&def_);
    def_.next_in = reinterpret_cast<Bytef*>(const_cast<float*>(log_odds));
    def_.avail_in = kBlockBytes;
    def_.next_out = reinterpret_cast<Bytef*>(out_.data());
    def_.avail_out = static_cast<uInt>(out_.size());
    if (deflate(&def_, Z_FINISH) != Z_STREAM_END) throw Error("zlib failed to compress an occupancy block");
    return {out_.data(), out_.size() - def_.avail_out};
  }
  // False when the blob is not exactly one block.
  bool decompress(std::span<const std::byte> blob, float* log_odds, int version) {
    if (version < 2) {  // zlib-wrapped, as version 1 wrote it
      uLongf size = kBlockBytes;
      return uncompress(reinterpret_cast<Bytef*>(log_odds), &size, reinterpret_cast<const Bytef*>(blob.data()),
                        blob.size()) == Z_OK &&
             size == kBlockBytes;
    }
    inflateReset(&inf_);
    inf_.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(blob.data()));
    inf_.avail_in = static_cast<uInt>(blob.size());
    inf_.next_out = reinterpret_cast<Bytef*>(log_odds);
    inf_.avail_out = kBlockBytes;
    return inflate(&inf_, Z_FINISH) == Z_STREAM_END && inf_.avail_out == 0 && inf_.avail_in == 0;
  }

 private:
  z_stream def_{}, inf_{};
  std::vector<std::byte> out_;
};

// Whether every log-odds is unknown (NaN) or inside the clamping range; branch-free, so it vectorises.
bool log_odds_possible(const float* v, float lo, float hi) {
  int bad = 0;
  for (int i = 0; i < kBlockVoxels; ++i) bad |= (v[i] == v[i]) & ((v[i] < lo) | (v[i] > hi));
  return !bad;
}

}  // namespace

const char* const kSchema = R"sql(
CREATE TABLE meta(key TEXT PRIMARY KEY NOT NULL, value TEXT NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE submaps(id INTEGER PRIMARY KEY NOT NULL, pose BLOB NOT NULL, time_begin REAL, time_end REAL,
  path_length REAL NOT NULL, blocks INTEGER NOT NULL, known_voxels INTEGER NOT NULL, occupied_voxels INTEGER NOT NULL,
  semantic_voxels INTEGER NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE occupancy(submap INTEGER NOT NULL, bx INTEGER NOT NULL, by INTEGER NOT NULL, bz INTEGER NOT NULL,
  log_odds BLOB NOT NULL, crc INTEGER NOT NULL);
CREATE TABLE semantics(submap INTEGER NOT NULL, chunk INTEGER NOT NULL, keys BLOB NOT NULL, counts BLOB NOT NULL,
  embeddings BLOB NOT NULL, crc INTEGER NOT NULL, stats BLOB NOT NULL, stats_crc INTEGER NOT NULL);
)sql";

const char* const kIndexes = R"sql(
CREATE INDEX IF NOT EXISTS occupancy_by_submap ON occupancy(submap);
CREATE INDEX IF NOT EXISTS semantics_by_submap ON semantics(submap, chunk);
)sql";

SubmapSummary summarize(const Submap& s) {
  const VoxelMap& v = s.voxels();
  return {s.info(), v.occupancy().num_blocks(), v.occupancy().num_known_voxels(), v.occupancy().num_occupied_voxels(),
          v.semantics().size()};
}

void write_submap_row(Database& db, const SubmapSummary& s) {
  Statement insert(db,
                   "INSERT INTO submaps(id, pose, time_begin, time_end, path_length, blocks, known_voxels, "
                   "occupied_voxels, semantic_voxels, crc) VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  const Eigen::Matrix4d pose = s.info.T_world_submap.matrix();  // column-major
  const auto pose_bytes = std::as_bytes(std::span(pose.data(), 16));
  insert.bind(1, int64_t{s.info.id}).bind(2, pose_bytes);
  if (s.info.time_range.empty()) insert.bind_null(3).bind_null(4);
  else insert.bind_real(3, s.info.time_range.begin).bind_real(4, s.info.time_range.end);
  insert.bind_real(5, s.info.path_length).bind(6, static_cast<int64_t>(s.blocks));
  insert.bind(7, static_cast<int64_t>(s.known_voxels)).bind(8, static_cast<int64_t>(s.occupied_voxels));
  insert.bind(9, static_cast<int64_t>(s.semantic_voxels)).bind(10, submap_crc(s, pose_bytes, 2)).insert();
}

std::vector<SubmapSummary> read_submap_rows(Database& db, int version) {
  std::vector<SubmapSummary> submaps;
  Statement rows(db, version >= 2 ? "SELECT id, pose, blocks, known_voxels, occupied_voxels, semantic_voxels, crc, "
                                    "time_begin, time_end, path_length FROM submaps ORDER BY id"
                                  : "SELECT id, pose, blocks, known_voxels, occupied_voxels, semantic_voxels, crc "
                                    "FROM submaps ORDER BY rowid");
  while (rows.step()) {
    const int64_t id = rows.int64(0);
    const auto pose = rows.blob(1);
    SubmapSummary s;
    s.info.id = static_cast<int>(id);
    s.info.finished = true;
    s.blocks = static_cast<std::size_t>(rows.int64(2));
    s.known_voxels = static_cast<std::size_t>(rows.int64(3));
    s.occupied_voxels = static_cast<std::size_t>(rows.int64(4));
    s.semantic_voxels = static_cast<std::size_t>(rows.int64(5));
    if (version >= 2) {
      if (!rows.is_null(7) || !rows.is_null(8)) s.info.time_range = {rows.real(7), rows.real(8)};
      s.info.path_length = rows.real(9);
    }
    if (id != s.info.id || submap_crc(s, pose, version) != rows.int64(6))
      throw Error(fmt::format("CRC mismatch in the row of submap {}: the file is corrupt", id));
    if (pose.size() != 16 * sizeof(double))
      throw Error(fmt::format("submap {} pose has {} bytes, expected 128", id, pose.size()));
    Eigen::Matrix4d m;
    std::memcpy(m.data(), pose.data(), pose.size());
    check_rigid_pose(s.info.id, m);
    s.info.T_world_submap.matrix() = m;
    const TimeRange& t = s.info.time_range;
    if (!std::isfinite(s.info.path_length) || s.info.path_length < 0 ||
        (!t.empty() && !(std::isfinite(t.begin) && std::isfinite(t.end))) ||
        (version >= 2 && rows.is_null(7) != rows.is_null(8)))
      throw Error(fmt::format("submap {} has an impossible time range or path length", id));
    submaps.push_back(s);
  }
  return submaps;
}

PayloadBytes write_submap_voxels(Database& db, const Submap& submap, EmbeddingPrecision precision) {
  PayloadBytes payload;
  const int64_t id = submap.id();
  const VoxelMap& voxels = submap.voxels();
  // Rows in key order, so that the same map always gives the same file.
  std::vector<std::pair<BlockKey, const OccupancyGrid::Block*>> blocks;
  for (const auto& [bk, b] : voxels.occupancy().blocks()) blocks.emplace_back(bk, b.get());
  std::sort(blocks.begin(), blocks.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  Statement occ(db, "INSERT INTO occupancy(submap, bx, by, bz, log_odds, crc) VALUES(?, ?, ?, ?, ?, ?)");
  std::array<float, kBlockVoxels> log_odds;
  BlockCodec codec;
  for (const auto& [bk, block] : blocks) {
    for (int i = 0; i < kBlockVoxels; ++i) log_odds[i] = block->cells[i].log_odds;
    const auto blob = codec.compress(log_odds.data());
    payload.occupancy += blob.size();
    const int64_t crc = Crc().add(id).add(bk.x()).add(bk.y()).add(bk.z()).add(blob).value();
    occ.bind(1, id).bind(2, bk.x()).bind(3, bk.y()).bind(4, bk.z()).bind(5, blob).bind(6, crc).insert();
  }

  const SemanticLayer& layer = voxels.semantics();
  std::vector<SemanticLayer::Handle> entries;
  entries.reserve(layer.size());
  layer.for_each([&](SemanticLayer::Handle h) { entries.push_back(h); });
  std::sort(entries.begin(), entries.end(), [&](auto a, auto b) { return layer.key_of(a) < layer.key_of(b); });
  const auto dim = static_cast<std::size_t>(layer.dim());
  const std::size_t value_bytes = bytes_per_value(precision);
  Statement sem(db,
                "INSERT INTO semantics(submap, chunk, keys, counts, embeddings, crc, stats, stats_crc) "
                "VALUES(?, ?, ?, ?, ?, ?, ?, ?)");
  std::vector<int32_t> keys;
  std::vector<uint32_t> counts;
  std::vector<VoxelStatistics> stats;
  std::vector<std::byte> embeddings;
  std::vector<float> row(dim);
  for (std::size_t begin = 0, chunk = 0; begin < entries.size(); begin += kSemanticChunkEntries, ++chunk) {
    const std::size_t n = std::min(kSemanticChunkEntries, entries.size() - begin);
    keys.resize(3 * n);
    counts.resize(n);
    stats.resize(n);
    embeddings.resize(n * dim * value_bytes);
    for (std::size_t j = 0; j < n; ++j) {
      const SemanticLayer::Handle h = entries[begin + j];
      const VoxelKey& k = layer.key_of(h);
      keys[3 * j] = k.x(), keys[3 * j + 1] = k.y(), keys[3 * j + 2] = k.z();
      counts[j] = layer.count_of(h);
      stats[j] = layer.statistics_of(h);
      std::byte* dst = embeddings.data() + j * dim * value_bytes;
      if (layer.precision() == precision) {
        std::memcpy(dst, layer.embedding_of(h).data, dim * value_bytes);
      } else {  // the active submap accumulates in fp32; files hold the storage precision
        layer.read(h, row.data());
        if (precision == EmbeddingPrecision::kFloat16) kernels::float_to_half(row.data(), reinterpret_cast<uint16_t*>(dst), dim);
        else std::memcpy(dst, row.data(), dim * value_bytes);
      }
    }
    const auto key_bytes = bytes_of(keys), count_bytes = bytes_of(counts), embedding_bytes = bytes_of(embeddings);
    const auto stats_bytes = bytes_of(stats);
    payload.semantics += key_bytes.size() + count_bytes.size() + embedding_bytes.size() + stats_bytes.size();
    const int64_t crc =
        Crc().add(id).add(static_cast<int64_t>(chunk)).add(key_bytes).add(count_bytes).add(embedding_bytes).value();
    const int64_t stats_crc = Crc().add(id).add(static_cast<int64_t>(chunk)).add(stats_bytes).value();
    sem.bind(1, id).bind(2, static_cast<int64_t>(chunk)).bind(3, key_bytes).bind(4, count_bytes).bind(5, embedding_bytes);
    sem.bind(6, crc).bind(7, stats_bytes).bind(8, stats_crc).insert();
  }
  return payload;
}

OccupancyGrid read_submap_occupancy(Database& db, int version, const SubmapSummary& summary, const MapParams& params) {
  const int64_t id = summary.info.id;
  OccupancyGrid grid(params.occupancy);
  const OccupancyParams& op = params.occupancy;
  Statement occ(db, "SELECT bx, by, bz, log_odds, crc FROM occupancy WHERE submap = ?");
  occ.bind(1, id);
  std::array<float, kBlockVoxels> log_odds;
  BlockCodec codec;
  std::size_t known = 0;
  while (occ.step()) {
    const int64_t bx = occ.int64(0), by = occ.int64(1), bz = occ.int64(2);
    const auto blob = occ.blob(3);
    if (Crc().add(id).add(bx).add(by).add(bz).add(blob).value() != occ.int64(4))
      throw Error(fmt::format("CRC mismatch in occupancy block ({}, {}, {}) of submap {}: the file is corrupt", bx, by,
                              bz, id));
    for (const int64_t c : {bx, by, bz})
      if (c <= -kMaxBlockCoordinate || c >= kMaxBlockCoordinate)
        throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} lies outside the representable extent", bx,
                                by, bz, id));
    if (blob.empty() || !codec.decompress(blob, log_odds.data(), version))
      throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} does not decompress to {} log-odds", bx, by, bz,
                              id, kBlockVoxels));
    if (!log_odds_possible(log_odds.data(), op.clamp_min - 1e-4f, op.clamp_max + 1e-4f))
      throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} holds log-odds outside [{}, {}]", bx, by, bz,
                              id, op.clamp_min, op.clamp_max));
    const BlockKey bk(static_cast<int>(bx), static_cast<int>(by), static_cast<int>(bz));
    if (grid.blocks().contains(bk))
      throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} appears twice", bx, by, bz, id));
    known += static_cast<std::size_t>(grid.set_block(bk, log_odds.data()));
  }

  // Missing rows (a damaged file SQLite itself did not notice) show up as wrong counts.
  if (grid.num_blocks() != summary.blocks || known != summary.known_voxels ||
      grid.num_occupied_voxels() != summary.occupied_voxels)
    throw Error(fmt::format("submap {} loaded with {} blocks, {} known, {} occupied voxels but was saved with {}, {}, {}: "
                            "rows are missing or duplicated",
                            id, grid.num_blocks(), known, grid.num_occupied_voxels(), summary.blocks,
                            summary.known_voxels, summary.occupied_voxels));
  return grid;
}

SemanticLayer read_submap_semantics(Database& db, int version, const SubmapSummary& summary, const MapParams& params) {
  const int64_t id = summary.info.id;
  SemanticLayer layer(params.semantic);
  const auto dim = static_cast<std::size_t>(params.semantic.dim);
  const EmbeddingPrecision precision = params.semantic.precision;
  const std::size_t embedding_bytes = dim * bytes_per_value(precision);
  Statement sem(db, version >= 3   ? "SELECT keys, counts, embeddings, crc, chunk, stats, stats_crc FROM semantics "
                                     "WHERE submap = ? ORDER BY chunk"
                    : version >= 2 ? "SELECT keys, counts, embeddings, crc, chunk FROM semantics WHERE submap = ? ORDER BY chunk"
                                   : "SELECT keys, counts, embeddings, crc FROM semantics WHERE submap = ? ORDER BY rowid");
  sem.bind(1, id);
  std::vector<VoxelKey> keys;
  std::vector<int32_t> raw_keys;
  std::vector<uint32_t> counts;
  std::vector<VoxelStatistics> stats;  // stays empty before version 3: statistics unknown
  for (int64_t chunk = 0; sem.step(); ++chunk) {
    const auto key_bytes = sem.blob(0), count_bytes = sem.blob(1), embedding_blob = sem.blob(2);
    Crc crc;
    crc.add(id);
    if (version >= 2) {
      if (sem.int64(4) != chunk) throw Error(fmt::format("semantic chunk {} of submap {} is missing", chunk, id));
      crc.add(chunk);
    }
    if (crc.add(key_bytes).add(count_bytes).add(embedding_blob).value() != sem.int64(3))
      throw Error(fmt::format("CRC mismatch in semantic chunk {} of submap {}: the file is corrupt", chunk, id));
    const std::size_t n = count_bytes.size() / sizeof(uint32_t);
    if (n == 0 || count_bytes.size() != n * sizeof(uint32_t) || key_bytes.size() != n * 3 * sizeof(int32_t) ||
        embedding_blob.size() != n * embedding_bytes)
      throw Error(fmt::format("semantic chunk {} of submap {} has inconsistent or empty blobs", chunk, id));
    raw_keys.resize(3 * n);
    counts.resize(n);
    std::memcpy(raw_keys.data(), key_bytes.data(), key_bytes.size());
    std::memcpy(counts.data(), count_bytes.data(), count_bytes.size());
    keys.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      keys[j] = VoxelKey(raw_keys[3 * j], raw_keys[3 * j + 1], raw_keys[3 * j + 2]);
      if (!in_grid_extent(keys[j].cast<double>()))
        throw Error(fmt::format("semantic chunk {} of submap {} has a key outside the representable extent", chunk, id));
    }
    if (!embeddings_finite(embedding_blob.data(), n * dim, precision))
      throw Error(fmt::format("semantic chunk {} of submap {} holds non-finite embeddings", chunk, id));
    if (version >= 3) {
      const auto stats_bytes = sem.blob(5);
      if (Crc().add(id).add(chunk).add(stats_bytes).value() != sem.int64(6))
        throw Error(fmt::format("CRC mismatch in the statistics of semantic chunk {} of submap {}: the file is corrupt",
                                chunk, id));
      if (stats_bytes.size() != n * sizeof(VoxelStatistics))
        throw Error(fmt::format("semantic chunk {} of submap {} has statistics for {} bytes, expected {}", chunk, id,
                                stats_bytes.size(), n * sizeof(VoxelStatistics)));
      stats.resize(n);
      std::memcpy(stats.data(), stats_bytes.data(), stats_bytes.size());
      // Weights are positive and finite; a spread is unknown (NaN: carried over from an older map)
      // or finite and not negative.
      for (const VoxelStatistics& st : stats)
        if (!(st.weight > 0.f) || !std::isfinite(st.weight) || (st.known() && !(st.spread >= 0.f && std::isfinite(st.spread))))
          throw Error(fmt::format("semantic chunk {} of submap {} holds impossible statistics (weight {}, spread {})",
                                  chunk, id, st.weight, st.spread));
    }
    try {
      layer.insert_raw(keys, counts, embedding_blob.data(), stats);
    } catch (const Error& e) {
      throw Error(fmt::format("semantic chunk {} of submap {}: {}", chunk, id, e.what()));
    }
  }

  if (layer.size() != summary.semantic_voxels)
    throw Error(fmt::format("submap {} loaded with {} semantic voxels but was saved with {}: rows are missing or duplicated",
                            id, layer.size(), summary.semantic_voxels));
  return layer;
}

void check_no_orphan_rows(Database& db) {
  for (const char* table : {"occupancy", "semantics"}) {
    Statement orphans(db, fmt::format("SELECT DISTINCT submap FROM {} WHERE submap NOT IN (SELECT id FROM submaps) LIMIT 1",
                                      table));
    if (orphans.step())
      throw Error(fmt::format("a row of table {} refers to submap {}, which is not in the file", table, orphans.int64(0)));
  }
}

}  // namespace slamvdb::store
