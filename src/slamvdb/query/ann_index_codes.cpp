#include "slamvdb/query/ann_index_codes.hpp"

#include <immintrin.h>

#include <algorithm>
#include <climits>
#include <cmath>

namespace slamvdb::ann_codes {
namespace {

#define SLAMVDB_ANN_CODES_AVX2 __attribute__((target("avx2")))

void score_codes_scalar(const uint8_t* codes, std::size_t count, std::size_t stride, const int16_t* weights,
                        int32_t* out) {
  for (std::size_t i = 0; i < count; ++i) {
    const uint8_t* c = codes + i * stride;
    int32_t s = 0;
    for (std::size_t d = 0; d < stride; ++d) s += static_cast<int32_t>(c[d]) * weights[d];
    out[i] = s;
  }
}

// 16 bytes widened to 16-bit lanes, multiplied by the weights and summed in pairs (vpmaddwd), with
// two accumulators; the weights (stride * 2 bytes) stay in L1 across codes.
SLAMVDB_ANN_CODES_AVX2 void score_codes_avx2(const uint8_t* codes, std::size_t count, std::size_t stride,
                                             const int16_t* weights, int32_t* out) {
  for (std::size_t i = 0; i < count; ++i) {
    const uint8_t* c = codes + i * stride;
    __m256i a0 = _mm256_setzero_si256(), a1 = _mm256_setzero_si256();
    std::size_t d = 0;
    for (; d + 32 <= stride; d += 32) {
      const __m256i c0 = _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c + d)));
      const __m256i c1 = _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c + d + 16)));
      a0 = _mm256_add_epi32(a0, _mm256_madd_epi16(c0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(weights + d))));
      a1 = _mm256_add_epi32(a1,
                            _mm256_madd_epi16(c1, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(weights + d + 16))));
    }
    if (d < stride) {
      const __m256i c0 = _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(c + d)));
      a0 = _mm256_add_epi32(a0, _mm256_madd_epi16(c0, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(weights + d))));
    }
    const __m256i a = _mm256_add_epi32(a0, a1);
    __m128i s = _mm_add_epi32(_mm256_castsi256_si128(a), _mm256_extracti128_si256(a, 1));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(1, 0, 3, 2)));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(2, 3, 0, 1)));
    out[i] = _mm_cvtsi128_si32(s);
  }
}

using ScoreCodes = void (*)(const uint8_t*, std::size_t, std::size_t, const int16_t*, int32_t*);

ScoreCodes choose_score_codes() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") ? score_codes_avx2 : score_codes_scalar;
}

}  // namespace

Sq8Codebook::Sq8Codebook(const float* rows, std::size_t n, std::size_t dim) : low_(dim, 0.f), step_(dim, 1.f) {
  for (std::size_t d = 0; d < dim; ++d) {
    float lo = n ? rows[d] : 0.f, hi = lo;
    for (std::size_t i = 1; i < n; ++i) {
      lo = std::min(lo, rows[i * dim + d]);
      hi = std::max(hi, rows[i * dim + d]);
    }
    low_[d] = lo;
    step_[d] = hi > lo ? (hi - lo) / 255.f : 1.f;  // a constant dimension: every code 0, its value low
  }
}

void Sq8Codebook::encode(const float* x, uint8_t* code) const {
  const std::size_t dim = low_.size();
  for (std::size_t d = 0; d < dim; ++d) {
    const float c = std::nearbyint((x[d] - low_[d]) / step_[d]);
    code[d] = static_cast<uint8_t>(std::clamp(c, 0.f, 255.f));
  }
  std::fill(code + dim, code + stride(), uint8_t{0});
}

std::vector<int16_t> Sq8Codebook::weights(const float* unit_query) const {
  const std::size_t dim = low_.size();
  std::vector<float> w(dim);
  float largest = 0;
  for (std::size_t d = 0; d < dim; ++d) {
    w[d] = unit_query[d] * step_[d];
    largest = std::max(largest, std::abs(w[d]));
  }
  // Scaled so that |sum| <= 255 * limit * dim stays below 2^31 (and each pair sum of vpmaddwd too).
  const double limit = std::min(8191.0, static_cast<double>(INT_MAX) / (255.0 * static_cast<double>(std::max<std::size_t>(dim, 1))));
  const double scale = largest > 0 ? limit / largest : 0.0;
  std::vector<int16_t> out(stride(), 0);
  for (std::size_t d = 0; d < dim; ++d) out[d] = static_cast<int16_t>(std::lround(w[d] * scale));
  return out;
}

void score_codes(const uint8_t* codes, std::size_t count, std::size_t stride, const int16_t* weights, int32_t* out) {
  static const ScoreCodes kernel = choose_score_codes();
  kernel(codes, count, stride, weights, out);
}

}  // namespace slamvdb::ann_codes
