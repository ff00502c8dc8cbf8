#include "slamvdb/map/semantic_layer.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

std::string_view to_string(EmbeddingPrecision p) { return p == EmbeddingPrecision::kFloat16 ? "fp16" : "fp32"; }

EmbeddingPrecision precision_from_string(std::string_view s) {
  if (s == "fp16") return EmbeddingPrecision::kFloat16;
  if (s == "fp32") return EmbeddingPrecision::kFloat32;
  throw Error(fmt::format("unknown embedding precision '{}' (expected fp16 or fp32)", s));
}

SemanticLayer::SemanticLayer(const SemanticParams& params) : params_(params) {
  if (params_.dim <= 0 || params_.dim > 65536)
    throw Error(fmt::format("embedding dimension {} out of range (1..65536)", params_.dim));
  bytes_per_embedding_ = static_cast<std::size_t>(params_.dim) * bytes_per_value(params_.precision);
}

SemanticLayer::Handle SemanticLayer::allocate(const VoxelKey& key) {
  Handle h;
  if (!free_slots_.empty()) {
    h = free_slots_.back();
    free_slots_.pop_back();
  } else {
    h = static_cast<Handle>(slots_used_++);
    if (h / kChunkSlots >= chunks_.size()) {
      auto c = std::make_unique<Chunk>();
      c->embeddings = std::make_unique_for_overwrite<std::byte[]>(kChunkSlots * bytes_per_embedding_);
      chunks_.push_back(std::move(c));
    }
  }
  Chunk& c = chunk(h);
  c.keys[h % kChunkSlots] = key;
  c.counts[h % kChunkSlots] = 0;
  c.stats[h % kChunkSlots] = {};
  c.sessions[h % kChunkSlots] = kOwnSession;
  index_.emplace(key, h);
  if (tracking_) changes_.added.push_back(h);
  return h;
}

void SemanticLayer::store_embedding(Handle h, const float* values) {
  const auto dim = static_cast<std::size_t>(params_.dim);
  if (params_.precision == EmbeddingPrecision::kFloat16)
    kernels::float_to_half(values, reinterpret_cast<uint16_t*>(embedding(h)), dim);
  else
    std::copy_n(values, dim, reinterpret_cast<float*>(embedding(h)));
}

void SemanticLayer::zero_embedding(Handle h) {
  const auto dim = static_cast<std::size_t>(params_.dim);
  if (params_.precision == EmbeddingPrecision::kFloat16)
    std::fill_n(reinterpret_cast<uint16_t*>(embedding(h)), dim, uint16_t{0});
  else
    std::fill_n(reinterpret_cast<float*>(embedding(h)), dim, 0.0f);
}

float SemanticLayer::step_embedding(Handle h, const float* x, float step) {
  const auto dim = static_cast<std::size_t>(params_.dim);
  return params_.precision == EmbeddingPrecision::kFloat16
             ? kernels::running_mean_sq(reinterpret_cast<uint16_t*>(embedding(h)), x, step, dim)
             : kernels::running_mean_sq(reinterpret_cast<float*>(embedding(h)), x, step, dim);
}

void SemanticLayer::integrate(const VoxelKey& key, const float* observation, float weight) {
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  uint32_t& n = count_ref(h);
  VoxelStatistics& st = stats_ref(h);
  if (n == 0) {
    st = {0.f, 0.f};
    zero_embedding(h);
  }
  // West (1979): W' = W + w, d = x - v, v += (w / W') d, S += w (W / W') |d|^2. With w = 1 the
  // weight sum is the count n exactly, and the step Eq. 6.1's 1 / (n + 1) as it was computed before.
  const float total = st.weight + weight;
  const float step = weight / total;
  const float d2 = step_embedding(h, observation, step);
  if (n > 0) st.spread += weight * (st.weight / total) * d2;
  st.weight = total;
  n = n == UINT32_MAX ? n : n + 1;
}

void SemanticLayer::keep_best(const VoxelKey& key, const float* observation, float weight) {
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  uint32_t& n = count_ref(h);
  VoxelStatistics& st = stats_ref(h);
  if (n == 0 || weight > st.weight) {
    store_embedding(h, observation);
    st = {weight, 0.f};
  }
  n = n == UINT32_MAX ? n : n + 1;
}

void SemanticLayer::accumulate(const VoxelKey& key, const float* mean, uint32_t count, VoxelStatistics stats) {
  if (count == 0) return;
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  uint32_t& n = count_ref(h);
  VoxelStatistics& st = stats_ref(h);
  const uint64_t total = uint64_t{n} + count;
  if (n == 0) {
    st = {0.f, 0.f};
    zero_embedding(h);
  }
  if (params_.single_view) {
    if (n == 0 || stats.weight > st.weight) {
      store_embedding(h, mean);
      st = stats;
    }
    n = static_cast<uint32_t>(std::min<uint64_t>(total, UINT32_MAX));
    return;
  }
  // Weighted by the statistics' weights (the counts under the paper's rule, as before).
  const double w_total = static_cast<double>(st.weight) + static_cast<double>(stats.weight);
  const auto w = static_cast<float>(w_total > 0 ? static_cast<double>(stats.weight) / w_total
                                                : static_cast<double>(count) / static_cast<double>(total));
  const float d2 = step_embedding(h, mean, w);
  st = n == 0 ? stats : combine_statistics(st, stats, d2);
  n = static_cast<uint32_t>(std::min<uint64_t>(total, UINT32_MAX));
}

void SemanticLayer::set(const VoxelKey& key, const float* values, uint32_t count) {
  set(key, values, count, unknown_statistics(count));
}

void SemanticLayer::set(const VoxelKey& key, const float* values, uint32_t count, VoxelStatistics stats) {
  if (count == 0) throw Error("semantic entry count must be >= 1");
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  count_ref(h) = count;
  stats_ref(h) = stats;
  store_embedding(h, values);
}

void SemanticLayer::insert_raw(std::span<const VoxelKey> keys, std::span<const uint32_t> counts,
                               const std::byte* embeddings, std::span<const VoxelStatistics> stats,
                               std::span<const uint16_t> sessions) {
  if (keys.size() != counts.size()) throw Error("insert_raw: keys and counts differ in length");
  if (!stats.empty() && stats.size() != keys.size()) throw Error("insert_raw: keys and statistics differ in length");
  if (!sessions.empty() && sessions.size() != keys.size()) throw Error("insert_raw: keys and sessions differ in length");
  index_.reserve(index_.size() + keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (counts[i] == 0) throw Error(fmt::format("semantic entry {} has a zero count", i));
    if (index_.contains(keys[i]))
      throw Error(fmt::format("semantic key ({}, {}, {}) appears twice", keys[i].x(), keys[i].y(), keys[i].z()));
    const Handle h = allocate(keys[i]);
    count_ref(h) = counts[i];
    stats_ref(h) = stats.empty() ? unknown_statistics(counts[i]) : stats[i];
    chunk(h).sessions[h % kChunkSlots] = sessions.empty() ? kOwnSession : sessions[i];
    std::memcpy(embedding(h), embeddings + i * bytes_per_embedding_, bytes_per_embedding_);
  }
}

namespace {
uint16_t checked_session(int session) {
  if (session < 0 || session >= SemanticLayer::kOwnSession)
    throw Error(fmt::format("session id {} out of range (0..{})", session, SemanticLayer::kOwnSession - 1));
  return static_cast<uint16_t>(session);
}
}  // namespace

void SemanticLayer::set_session(Handle h, int session) {
  chunk(h).sessions[h % kChunkSlots] = session == own_session_ ? kOwnSession : checked_session(session);
}

bool SemanticLayer::has_other_sessions() const {
  bool other = false;
  for_each([&](Handle h) { other = other || stored_session_of(h) != kOwnSession; });
  return other;
}

void SemanticLayer::set_own_session(int session) { own_session_ = checked_session(session); }

void SemanticLayer::renumber_sessions(const std::map<int, int>& new_id_of_old) {
  const auto new_id = [&](int old) {
    const auto it = new_id_of_old.find(old);
    if (it == new_id_of_old.end())
      throw Error(fmt::format("a semantic entry was last observed in session {}, which the map does not list", old));
    return checked_session(it->second);
  };
  std::map<uint16_t, uint16_t> table;  // checked in full before anything changes
  const uint16_t own = new_id(own_session_);
  for_each([&](Handle h) {
    const uint16_t s = stored_session_of(h);
    if (s != kOwnSession && !table.count(s)) table[s] = new_id(s);
  });
  own_session_ = own;
  for (auto& c : chunks_)
    for (uint16_t& s : c->sessions) {
      const auto it = table.find(s);
      if (it != table.end()) s = it->second;  // free slots may hold anything
    }
}

bool SemanticLayer::erase(const VoxelKey& key) {
  const auto it = index_.find(key);
  if (it == index_.end()) return false;
  const Handle h = it->second;
  count_ref(h) = 0;
  index_.erase(it);
  if (tracking_) {
    changes_.erased.emplace_back(h, key);
    pending_free_.push_back(h);
  } else {
    free_slots_.push_back(h);
  }
  return true;
}

std::optional<SemanticLayer::Handle> SemanticLayer::find(const VoxelKey& key) const {
  const auto it = index_.find(key);
  if (it == index_.end()) return std::nullopt;
  return it->second;
}

void SemanticLayer::read(Handle h, float* out) const {
  kernels::decode(embedding_of(h), out, static_cast<std::size_t>(params_.dim));
}

void SemanticLayer::convert_to(EmbeddingPrecision precision) {
  if (precision == params_.precision) return;
  const auto dim = static_cast<std::size_t>(params_.dim);
  const std::size_t new_bytes = dim * bytes_per_value(precision);
  std::vector<float> row(dim);
  for (std::size_t c = 0; c < chunks_.size(); ++c) {
    Chunk& ch = *chunks_[c];
    auto converted = std::make_unique_for_overwrite<std::byte[]>(kChunkSlots * new_bytes);
    for (std::size_t s = 0; s < kChunkSlots; ++s) {
      if (!ch.counts[s]) continue;
      kernels::decode({ch.embeddings.get() + s * bytes_per_embedding_, params_.precision}, row.data(), dim);
      std::byte* dst = converted.get() + s * new_bytes;
      if (precision == EmbeddingPrecision::kFloat16)
        kernels::float_to_half(row.data(), reinterpret_cast<uint16_t*>(dst), dim);
      else
        std::memcpy(dst, row.data(), new_bytes);
    }
    ch.embeddings = std::move(converted);
  }
  params_.precision = precision;
  bytes_per_embedding_ = new_bytes;
}

void SemanticLayer::set_change_tracking(bool on) {
  if (!on) take_changes();
  tracking_ = on;
}

SemanticLayer::Changes SemanticLayer::take_changes() {
  free_slots_.insert(free_slots_.end(), pending_free_.begin(), pending_free_.end());
  pending_free_.clear();
  return std::exchange(changes_, {});
}

std::size_t SemanticLayer::memory_bytes() const {
  return chunks_.size() * (sizeof(Chunk) + kChunkSlots * bytes_per_embedding_) +
         chunks_.capacity() * sizeof(std::unique_ptr<Chunk>) +
         (free_slots_.capacity() + pending_free_.capacity()) * sizeof(Handle) +
         index_.capacity() * (sizeof(std::pair<VoxelKey, Handle>) + 1);  // slots + absl control bytes
}

}  // namespace slamvdb
