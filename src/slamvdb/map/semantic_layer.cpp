#include "slamvdb/map/semantic_layer.hpp"

#include <fmt/format.h>

#include <algorithm>
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
  index_.emplace(key, h);
  if (tracking_) changes_.added.push_back(h);
  return h;
}

void SemanticLayer::integrate(const VoxelKey& key, const float* observation) {
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  uint32_t& n = count_ref(h);
  const float w = 1.0f / (static_cast<float>(n) + 1.0f);  // n = 0: the entry becomes the observation
  const auto dim = static_cast<std::size_t>(params_.dim);
  if (params_.precision == EmbeddingPrecision::kFloat16) {
    auto* v = reinterpret_cast<uint16_t*>(embedding(h));
    if (n == 0) std::fill_n(v, dim, uint16_t{0});
    kernels::running_mean(v, observation, w, dim);
  } else {
    auto* v = reinterpret_cast<float*>(embedding(h));
    if (n == 0) std::fill_n(v, dim, 0.0f);
    kernels::running_mean(v, observation, w, dim);
  }
  n = n == UINT32_MAX ? n : n + 1;
}

void SemanticLayer::accumulate(const VoxelKey& key, const float* mean, uint32_t count) {
  if (count == 0) return;
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  uint32_t& n = count_ref(h);
  const uint64_t total = uint64_t{n} + count;
  const auto w = static_cast<float>(static_cast<double>(count) / static_cast<double>(total));
  const auto dim = static_cast<std::size_t>(params_.dim);
  if (params_.precision == EmbeddingPrecision::kFloat16) {
    auto* v = reinterpret_cast<uint16_t*>(embedding(h));
    if (n == 0) std::fill_n(v, dim, uint16_t{0});
    kernels::running_mean(v, mean, w, dim);
  } else {
    auto* v = reinterpret_cast<float*>(embedding(h));
    if (n == 0) std::fill_n(v, dim, 0.0f);
    kernels::running_mean(v, mean, w, dim);
  }
  n = static_cast<uint32_t>(std::min<uint64_t>(total, UINT32_MAX));
}

void SemanticLayer::set(const VoxelKey& key, const float* values, uint32_t count) {
  if (count == 0) throw Error("semantic entry count must be >= 1");
  const auto it = index_.find(key);
  const Handle h = it != index_.end() ? it->second : allocate(key);
  count_ref(h) = count;
  const auto dim = static_cast<std::size_t>(params_.dim);
  if (params_.precision == EmbeddingPrecision::kFloat16)
    kernels::float_to_half(values, reinterpret_cast<uint16_t*>(embedding(h)), dim);
  else
    std::copy_n(values, dim, reinterpret_cast<float*>(embedding(h)));
}

void SemanticLayer::insert_raw(std::span<const VoxelKey> keys, std::span<const uint32_t> counts,
                               const std::byte* embeddings) {
  if (keys.size() != counts.size()) throw Error("insert_raw: keys and counts differ in length");
  index_.reserve(index_.size() + keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (counts[i] == 0) throw Error(fmt::format("semantic entry {} has a zero count", i));
    if (index_.contains(keys[i]))
      throw Error(fmt::format("semantic key ({}, {}, {}) appears twice", keys[i].x(), keys[i].y(), keys[i].z()));
    const Handle h = allocate(keys[i]);
    count_ref(h) = counts[i];
    std::memcpy(embedding(h), embeddings + i * bytes_per_embedding_, bytes_per_embedding_);
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
