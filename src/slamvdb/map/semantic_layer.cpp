#include "slamvdb/map/semantic_layer.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"

namespace slamvdb {

namespace {

// v <- v + (x - v) * w, the running mean of Eq. 6.1 with w = 1 / (n + 1).
void running_mean_fp32(float* v, const float* x, float w, int dim) {
  for (int i = 0; i < dim; ++i) v[i] += (x[i] - v[i]) * w;
}

void running_mean_fp16(uint16_t* v, const float* x, float w, int dim) {
  int i = 0;
#if defined(__F16C__) && defined(__AVX2__)
  const __m256 wv = _mm256_set1_ps(w);
  for (; i + 8 <= dim; i += 8) {
    const __m256 old = _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(v + i)));
    const __m256 upd = _mm256_fmadd_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), old), wv, old);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(v + i), _mm256_cvtps_ph(upd, _MM_FROUND_TO_NEAREST_INT));
  }
#endif
  for (; i < dim; ++i) {
    const float old = half_to_float(v[i]);
    v[i] = float_to_half(old + (x[i] - old) * w);
  }
}

}  // namespace

std::string_view to_string(EmbeddingPrecision p) { return p == EmbeddingPrecision::kFloat16 ? "fp16" : "fp32"; }

EmbeddingPrecision precision_from_string(std::string_view s) {
  if (s == "fp16") return EmbeddingPrecision::kFloat16;
  if (s == "fp32") return EmbeddingPrecision::kFloat32;
  throw Error(fmt::format("unknown embedding precision '{}' (expected fp16 or fp32)", s));
}

SemanticLayer::SemanticLayer(const SemanticParams& params) : params_(params) {
  if (params_.dim <= 0 || params_.dim > 65536)
    throw Error(fmt::format("embedding dimension {} out of range (1..65536)", params_.dim));
  bytes_per_embedding_ = static_cast<std::size_t>(params_.dim) *
                         (params_.precision == EmbeddingPrecision::kFloat16 ? sizeof(uint16_t) : sizeof(float));
}

SemanticLayer::Slot SemanticLayer::allocate(const VoxelKey& key) {
  Slot s;
  if (!free_slots_.empty()) {
    s = free_slots_.back();
    free_slots_.pop_back();
  } else {
    s = static_cast<Slot>(counts_.size());
    counts_.push_back(0);
    if (s / kChunkSlots >= chunks_.size())
      chunks_.push_back(std::make_unique_for_overwrite<std::byte[]>(kChunkSlots * bytes_per_embedding_));
  }
  counts_[s] = 0;
  index_.emplace(key, s);
  return s;
}

void SemanticLayer::integrate(const VoxelKey& key, const float* observation) {
  const auto it = index_.find(key);
  const Slot s = it != index_.end() ? it->second : allocate(key);
  const uint32_t n = counts_[s];
  const float w = 1.0f / static_cast<float>(n + 1);  // n = 0: the entry becomes the observation
  if (params_.precision == EmbeddingPrecision::kFloat16) {
    auto* v = reinterpret_cast<uint16_t*>(embedding(s));
    if (n == 0) std::fill_n(v, params_.dim, uint16_t{0});
    running_mean_fp16(v, observation, w, params_.dim);
  } else {
    auto* v = reinterpret_cast<float*>(embedding(s));
    if (n == 0) std::fill_n(v, params_.dim, 0.0f);
    running_mean_fp32(v, observation, w, params_.dim);
  }
  counts_[s] = n == UINT32_MAX ? n : n + 1;
}

void SemanticLayer::set(const VoxelKey& key, const float* values, uint32_t count) {
  if (count == 0) throw Error("semantic entry count must be >= 1");
  const auto it = index_.find(key);
  const Slot s = it != index_.end() ? it->second : allocate(key);
  counts_[s] = count;
  if (params_.precision == EmbeddingPrecision::kFloat16) {
    auto* v = reinterpret_cast<uint16_t*>(embedding(s));
    for (int i = 0; i < params_.dim; ++i) v[i] = float_to_half(values[i]);
  } else {
    std::copy_n(values, params_.dim, reinterpret_cast<float*>(embedding(s)));
  }
}

bool SemanticLayer::erase(const VoxelKey& key) {
  const auto it = index_.find(key);
  if (it == index_.end()) return false;
  counts_[it->second] = 0;
  free_slots_.push_back(it->second);
  index_.erase(it);
  return true;
}

std::optional<SemanticLayer::Slot> SemanticLayer::find(const VoxelKey& key) const {
  const auto it = index_.find(key);
  if (it == index_.end()) return std::nullopt;
  return it->second;
}

void SemanticLayer::read(Slot s, float* out) const {
  if (params_.precision == EmbeddingPrecision::kFloat16) {
    const auto* v = reinterpret_cast<const uint16_t*>(embedding(s));
    for (int i = 0; i < params_.dim; ++i) out[i] = half_to_float(v[i]);
  } else {
    std::copy_n(reinterpret_cast<const float*>(embedding(s)), params_.dim, out);
  }
}

std::size_t SemanticLayer::memory_bytes() const {
  return chunks_.size() * kChunkSlots * bytes_per_embedding_ + counts_.capacity() * sizeof(uint32_t) +
         free_slots_.capacity() * sizeof(Slot) +
         index_.capacity() * (sizeof(std::pair<VoxelKey, Slot>) + 1);  // slots + absl control bytes
}

}  // namespace slamvdb
