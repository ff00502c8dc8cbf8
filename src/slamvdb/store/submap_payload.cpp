// One submap's payload rows: encoding in key order and reading back with every value checked
// (shared by the map file and the fleet map, submap_payload.hpp).
#include "slamvdb/store/submap_payload.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/store/sqlite_db.hpp"  // Crc

namespace slamvdb::store {

// Named (not anonymous): OccupancyRowReader::Codec, declared in the header, derives from it.
namespace payload_detail {

constexpr std::size_t kBlockBytes = kBlockVoxels * sizeof(float);

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

}  // namespace payload_detail

namespace {

using payload_detail::BlockCodec;
using payload_detail::kBlockBytes;

static_assert(std::endian::native == std::endian::little, "map blobs hold host-order numbers, which must be LE");

// Block keys are shifted by 3 bits into voxel keys, which stay within the grid extent (keys.hpp).
constexpr int64_t kMaxBlockCoordinate = static_cast<int64_t>(kMaxGridCoordinate) >> kBlockBits;

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

// Whether every log-odds is unknown (NaN) or inside the clamping range; branch-free, so it vectorises.
bool log_odds_possible(const float* v, float lo, float hi) {
  int bad = 0;
  for (int i = 0; i < kBlockVoxels; ++i) bad |= (v[i] == v[i]) & ((v[i] < lo) | (v[i] > hi));
  return !bad;
}

}  // namespace

struct OccupancyRowReader::Codec : payload_detail::BlockCodec {};

PayloadBytes encode_submap_payload(const Submap& submap, EmbeddingPrecision precision,
                                   const std::function<void(const OccupancyRow&)>& occupancy_row,
                                   const std::function<void(const SemanticChunkRow&)>& semantic_row) {
  PayloadBytes payload;
  const int64_t id = submap.id();
  const VoxelMap& voxels = submap.voxels();
  // Rows in key order, so that the same map always gives the same rows.
  std::vector<std::pair<BlockKey, const OccupancyGrid::Block*>> blocks;
  for (const auto& [bk, b] : voxels.occupancy().blocks()) blocks.emplace_back(bk, b.get());
  std::sort(blocks.begin(), blocks.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::array<float, kBlockVoxels> log_odds;
  BlockCodec codec;
  for (const auto& [bk, block] : blocks) {
    for (int i = 0; i < kBlockVoxels; ++i) log_odds[i] = block->cells[i].log_odds;
    const auto blob = codec.compress(log_odds.data());
    payload.occupancy += blob.size();
    const int64_t crc = Crc().add(id).add(bk.x()).add(bk.y()).add(bk.z()).add(blob).value();
    occupancy_row({bk, blob, crc});
  }

  const SemanticLayer& layer = voxels.semantics();
  std::vector<SemanticLayer::Handle> entries;
  entries.reserve(layer.size());
  layer.for_each([&](SemanticLayer::Handle h) { entries.push_back(h); });
  std::sort(entries.begin(), entries.end(), [&](auto a, auto b) { return layer.key_of(a) < layer.key_of(b); });
  const auto dim = static_cast<std::size_t>(layer.dim());
  const std::size_t value_bytes = bytes_per_value(precision);
  std::vector<int32_t> keys;
  std::vector<uint32_t> counts;
  std::vector<VoxelStatistics> stats;
  std::vector<uint16_t> sessions;
  std::vector<std::byte> embeddings;
  std::vector<float> row(dim);
  for (std::size_t begin = 0, chunk = 0; begin < entries.size(); begin += kSemanticChunkEntries, ++chunk) {
    const std::size_t n = std::min(kSemanticChunkEntries, entries.size() - begin);
    keys.resize(3 * n);
    counts.resize(n);
    stats.resize(n);
    sessions.resize(n);
    bool other_sessions = false;
    embeddings.resize(n * dim * value_bytes);
    for (std::size_t j = 0; j < n; ++j) {
      const SemanticLayer::Handle h = entries[begin + j];
      const VoxelKey& k = layer.key_of(h);
      keys[3 * j] = k.x(), keys[3 * j + 1] = k.y(), keys[3 * j + 2] = k.z();
      counts[j] = layer.count_of(h);
      stats[j] = layer.statistics_of(h);
      sessions[j] = layer.stored_session_of(h);
      other_sessions = other_sessions || sessions[j] != SemanticLayer::kOwnSession;
      std::byte* dst = embeddings.data() + j * dim * value_bytes;
      if (layer.precision() == precision) {
        std::memcpy(dst, layer.embedding_of(h).data, dim * value_bytes);
      } else {  // the active submap accumulates in fp32; files hold the storage precision
        layer.read(h, row.data());
        if (precision == EmbeddingPrecision::kFloat16) kernels::float_to_half(row.data(), reinterpret_cast<uint16_t*>(dst), dim);
        else std::memcpy(dst, row.data(), dim * value_bytes);
      }
    }
    SemanticChunkRow out;
    out.chunk = static_cast<int64_t>(chunk);
    out.keys = bytes_of(keys), out.counts = bytes_of(counts), out.embeddings = bytes_of(embeddings);
    out.stats = bytes_of(stats);
    payload.semantics += out.keys.size() + out.counts.size() + out.embeddings.size() + out.stats.size();
    out.crc = Crc().add(id).add(out.chunk).add(out.keys).add(out.counts).add(out.embeddings).value();
    out.stats_crc = Crc().add(id).add(out.chunk).add(out.stats).value();
    if (other_sessions) {  // else NULL: a map of one session pays nothing
      out.sessions = bytes_of(sessions);
      out.sessions_crc = Crc().add(id).add(out.chunk).add(out.sessions).value();
      payload.semantics += out.sessions.size();
    }
    semantic_row(out);
  }
  return payload;
}

OccupancyRowReader::OccupancyRowReader(int64_t submap_id, int format_version, const MapParams& params)
    : id_(submap_id), version_(format_version), params_(params.occupancy), grid_(params.occupancy),
      codec_(std::make_unique<Codec>()) {}

OccupancyRowReader::~OccupancyRowReader() = default;

void OccupancyRowReader::add(int64_t bx, int64_t by, int64_t bz, std::span<const std::byte> blob, int64_t crc) {
  const int64_t id = id_;
  if (Crc().add(id).add(bx).add(by).add(bz).add(blob).value() != crc)
    throw Error(fmt::format("CRC mismatch in occupancy block ({}, {}, {}) of submap {}: the file is corrupt", bx, by,
                            bz, id));
  for (const int64_t c : {bx, by, bz})
    if (c <= -kMaxBlockCoordinate || c >= kMaxBlockCoordinate)
      throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} lies outside the representable extent", bx, by,
                              bz, id));
  std::array<float, kBlockVoxels> log_odds;
  if (blob.empty() || !codec_->decompress(blob, log_odds.data(), version_))
    throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} does not decompress to {} log-odds", bx, by, bz,
                            id, kBlockVoxels));
  if (!log_odds_possible(log_odds.data(), params_.clamp_min - 1e-4f, params_.clamp_max + 1e-4f))
    throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} holds log-odds outside [{}, {}]", bx, by, bz, id,
                            params_.clamp_min, params_.clamp_max));
  const BlockKey bk(static_cast<int>(bx), static_cast<int>(by), static_cast<int>(bz));
  if (grid_.blocks().contains(bk))
    throw Error(fmt::format("occupancy block ({}, {}, {}) of submap {} appears twice", bx, by, bz, id));
  known_ += static_cast<std::size_t>(grid_.set_block(bk, log_odds.data()));
}

OccupancyGrid OccupancyRowReader::finish(const SubmapSummary& summary) {
  // Missing rows (a damaged file SQLite itself did not notice) show up as wrong counts.
  if (grid_.num_blocks() != summary.blocks || known_ != summary.known_voxels ||
      grid_.num_occupied_voxels() != summary.occupied_voxels)
    throw Error(fmt::format("submap {} loaded with {} blocks, {} known, {} occupied voxels but was saved with {}, {}, {}: "
                            "rows are missing or duplicated",
                            id_, grid_.num_blocks(), known_, grid_.num_occupied_voxels(), summary.blocks,
                            summary.known_voxels, summary.occupied_voxels));
  return std::move(grid_);
}

SemanticChunkReader::SemanticChunkReader(int64_t submap_id, int format_version, const MapParams& params)
    : id_(submap_id), version_(format_version), params_(params.semantic), layer_(params.semantic) {}

void SemanticChunkReader::add(std::optional<int64_t> chunk_number, std::span<const std::byte> key_bytes,
                              std::span<const std::byte> count_bytes, std::span<const std::byte> embedding_blob,
                              int64_t stored_crc, std::span<const std::byte> stats_bytes, int64_t stored_stats_crc,
                              std::optional<std::span<const std::byte>> session_bytes,
                              std::optional<int64_t> stored_sessions_crc) {
  const int64_t id = id_, chunk = next_chunk_++;
  const auto dim = static_cast<std::size_t>(params_.dim);
  const EmbeddingPrecision precision = params_.precision;
  const std::size_t embedding_bytes = dim * bytes_per_value(precision);
  Crc crc;
  crc.add(id);
  if (version_ >= 2) {
    if (chunk_number != chunk) throw Error(fmt::format("semantic chunk {} of submap {} is missing", chunk, id));
    crc.add(chunk);
  }
  if (crc.add(key_bytes).add(count_bytes).add(embedding_blob).value() != stored_crc)
    throw Error(fmt::format("CRC mismatch in semantic chunk {} of submap {}: the file is corrupt", chunk, id));
  const std::size_t n = count_bytes.size() / sizeof(uint32_t);
  if (n == 0 || count_bytes.size() != n * sizeof(uint32_t) || key_bytes.size() != n * 3 * sizeof(int32_t) ||
      embedding_blob.size() != n * embedding_bytes)
    throw Error(fmt::format("semantic chunk {} of submap {} has inconsistent or empty blobs", chunk, id));
  raw_keys_.resize(3 * n);
  counts_.resize(n);
  std::memcpy(raw_keys_.data(), key_bytes.data(), key_bytes.size());
  std::memcpy(counts_.data(), count_bytes.data(), count_bytes.size());
  keys_.resize(n);
  for (std::size_t j = 0; j < n; ++j) {
    keys_[j] = VoxelKey(raw_keys_[3 * j], raw_keys_[3 * j + 1], raw_keys_[3 * j + 2]);
    if (!in_grid_extent(keys_[j].cast<double>()))
      throw Error(fmt::format("semantic chunk {} of submap {} has a key outside the representable extent", chunk, id));
  }
  if (!embeddings_finite(embedding_blob.data(), n * dim, precision))
    throw Error(fmt::format("semantic chunk {} of submap {} holds non-finite embeddings", chunk, id));
  stats_.clear();  // stays empty before version 3: statistics unknown
  if (version_ >= 3) {
    if (Crc().add(id).add(chunk).add(stats_bytes).value() != stored_stats_crc)
      throw Error(fmt::format("CRC mismatch in the statistics of semantic chunk {} of submap {}: the file is corrupt",
                              chunk, id));
    if (stats_bytes.size() != n * sizeof(VoxelStatistics))
      throw Error(fmt::format("semantic chunk {} of submap {} has statistics for {} bytes, expected {}", chunk, id,
                              stats_bytes.size(), n * sizeof(VoxelStatistics)));
    stats_.resize(n);
    std::memcpy(stats_.data(), stats_bytes.data(), stats_bytes.size());
    // Weights are positive and finite; a spread is unknown (NaN: carried over from an older map)
    // or finite and not negative.
    for (const VoxelStatistics& st : stats_)
      if (!(st.weight > 0.f) || !std::isfinite(st.weight) || (st.known() && !(st.spread >= 0.f && std::isfinite(st.spread))))
        throw Error(fmt::format("semantic chunk {} of submap {} holds impossible statistics (weight {}, spread {})",
                                chunk, id, st.weight, st.spread));
  }
  sessions_.clear();  // stays empty before version 5 or when NULL: every entry is the submap's own
  if (session_bytes.has_value() != stored_sessions_crc.has_value())
    throw Error(fmt::format("semantic chunk {} of submap {} has last-observed sessions without their CRC or a CRC "
                            "without sessions: the file is corrupt",
                            chunk, id));
  if (version_ >= 5 && session_bytes) {
    if (Crc().add(id).add(chunk).add(*session_bytes).value() != *stored_sessions_crc)
      throw Error(fmt::format("CRC mismatch in the last-observed sessions of semantic chunk {} of submap {}: the file "
                              "is corrupt",
                              chunk, id));
    if (session_bytes->size() != n * sizeof(uint16_t))
      throw Error(fmt::format("semantic chunk {} of submap {} has last-observed sessions for {} bytes, expected {}",
                              chunk, id, session_bytes->size(), n * sizeof(uint16_t)));
    sessions_.resize(n);
    std::memcpy(sessions_.data(), session_bytes->data(), session_bytes->size());
  }
  try {
    layer_.insert_raw(keys_, counts_, embedding_blob.data(), stats_, sessions_);
  } catch (const Error& e) {
    throw Error(fmt::format("semantic chunk {} of submap {}: {}", chunk, id, e.what()));
  }
}

SemanticLayer SemanticChunkReader::finish(const SubmapSummary& summary) {
  if (layer_.size() != summary.semantic_voxels)
    throw Error(fmt::format("submap {} loaded with {} semantic voxels but was saved with {}: rows are missing or duplicated",
                            id_, layer_.size(), summary.semantic_voxels));
  return std::move(layer_);
}

}  // namespace slamvdb::store
