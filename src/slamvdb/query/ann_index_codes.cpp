#include "slamvdb/query/ann_index_codes.hpp"

#include <immintrin.h>

#include <algorithm>
#include <climits>
#include <cmath>

namespace slamvdb::ann_codes {
namespace {

#define SLAMVDB_ANN_CODES_AVX2 __attribute__((target("avx2")))
#define SLAMVDB_ANN_CODES_VNNI __attribute__((target("avx2,avx512f,avx512bw,avx512vnni")))

// The kernels are written by hand: faiss's scanners return approximate distances of whole 8-bit
// (or 4-bit fast-scan, 16-dimension product) codes on its own threads, not an integer ranking of
// one nibble plane per dimension that the fine plane and the map's exact scores then refine.

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

void score_nibbles_scalar(const uint8_t* planes, std::size_t count, std::size_t plane_bytes, const int8_t* weights,
                          int32_t* out) {
  for (std::size_t i = 0; i < count; ++i) {
    const uint8_t* p = planes + i * plane_bytes;
    int32_t s = 0;
    for (std::size_t b = 0; b < plane_bytes; b += 64)
      for (std::size_t j = 0; j < 64; ++j) {
        s += static_cast<int32_t>(p[b + j] & 15) * weights[2 * b + j];
        s += static_cast<int32_t>(p[b + j] >> 4) * weights[2 * b + 64 + j];
      }
    out[i] = s;
  }
}

SLAMVDB_ANN_CODES_AVX2 inline __m256i load(const void* p) { return _mm256_loadu_si256(static_cast<const __m256i*>(p)); }

// Nibbles (0..15) times signed bytes summed in pairs (vpmaddubsw; four such sums stay below 2^15),
// then widened to 32 bits against ones (vpmaddwd).
SLAMVDB_ANN_CODES_AVX2 void score_nibbles_avx2(const uint8_t* planes, std::size_t count, std::size_t plane_bytes,
                                               const int8_t* weights, int32_t* out) {
  const __m256i mask = _mm256_set1_epi8(0x0F), ones = _mm256_set1_epi16(1);
  for (std::size_t i = 0; i < count; ++i) {
    const uint8_t* p = planes + i * plane_bytes;
    __m256i acc = _mm256_setzero_si256();
    for (std::size_t b = 0; b < plane_bytes; b += 64) {
      const __m256i x0 = load(p + b), x1 = load(p + b + 32);
      const int8_t* w = weights + 2 * b;
      __m256i s = _mm256_maddubs_epi16(_mm256_and_si256(x0, mask), load(w));
      s = _mm256_add_epi16(s, _mm256_maddubs_epi16(_mm256_and_si256(x1, mask), load(w + 32)));
      s = _mm256_add_epi16(s, _mm256_maddubs_epi16(_mm256_and_si256(_mm256_srli_epi16(x0, 4), mask), load(w + 64)));
      s = _mm256_add_epi16(s, _mm256_maddubs_epi16(_mm256_and_si256(_mm256_srli_epi16(x1, 4), mask), load(w + 96)));
      acc = _mm256_add_epi32(acc, _mm256_madd_epi16(s, ones));
    }
    __m128i s = _mm_add_epi32(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(1, 0, 3, 2)));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, _MM_SHUFFLE(2, 3, 0, 1)));
    out[i] = _mm_cvtsi128_si32(s);
  }
}

// A 64-byte load is 128 nibbles: both halves go through vpdpbusd (unsigned bytes times signed
// bytes, four products added into each 32-bit lane) against their 64 weights. Four codes at a time,
// their sums reduced together (one reduction per code would cost as much as its dot product).
SLAMVDB_ANN_CODES_VNNI inline __m512i nibble_dot_vnni(const uint8_t* p, std::size_t plane_bytes, const int8_t* weights) {
  const __m512i mask = _mm512_set1_epi8(0x0F);
  __m512i lo = _mm512_setzero_si512(), hi = _mm512_setzero_si512();
  for (std::size_t b = 0; b < plane_bytes; b += 64) {
    const __m512i x = _mm512_loadu_si512(p + b);
    lo = _mm512_dpbusd_epi32(lo, _mm512_and_si512(x, mask), _mm512_loadu_si512(weights + 2 * b));
    hi = _mm512_dpbusd_epi32(hi, _mm512_and_si512(_mm512_srli_epi16(x, 4), mask), _mm512_loadu_si512(weights + 2 * b + 64));
  }
  return _mm512_add_epi32(lo, hi);
}

SLAMVDB_ANN_CODES_VNNI inline __m128i fold_to_128(__m512i a) {
  const __m256i h = _mm256_add_epi32(_mm512_castsi512_si256(a), _mm512_extracti64x4_epi64(a, 1));
  return _mm_add_epi32(_mm256_castsi256_si128(h), _mm256_extracti128_si256(h, 1));
}

SLAMVDB_ANN_CODES_VNNI void score_nibbles_vnni(const uint8_t* planes, std::size_t count, std::size_t plane_bytes,
                                               const int8_t* weights, int32_t* out) {
  std::size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    const uint8_t* p = planes + i * plane_bytes;
    const __m128i a = fold_to_128(nibble_dot_vnni(p, plane_bytes, weights));
    const __m128i b = fold_to_128(nibble_dot_vnni(p + plane_bytes, plane_bytes, weights));
    const __m128i c = fold_to_128(nibble_dot_vnni(p + 2 * plane_bytes, plane_bytes, weights));
    const __m128i d = fold_to_128(nibble_dot_vnni(p + 3 * plane_bytes, plane_bytes, weights));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), _mm_hadd_epi32(_mm_hadd_epi32(a, b), _mm_hadd_epi32(c, d)));
  }
  for (; i < count; ++i) out[i] = _mm512_reduce_add_epi32(nibble_dot_vnni(planes + i * plane_bytes, plane_bytes, weights));
}

SLAMVDB_ANN_CODES_AVX2 void join_planes_avx2(const uint8_t* coarse, const uint8_t* fine, std::size_t plane_bytes,
                                             uint8_t* code) {
  const __m256i low4 = _mm256_set1_epi8(0x0F), high4 = _mm256_set1_epi8(static_cast<char>(0xF0));
  for (std::size_t b = 0; b < plane_bytes; b += 32) {
    const __m256i c = load(coarse + b), f = load(fine + b);
    const std::size_t at = b / 64 * 128 + b % 64;  // dimension of the low nibbles of these bytes
    const __m256i lows = _mm256_or_si256(_mm256_and_si256(_mm256_slli_epi16(c, 4), high4), _mm256_and_si256(f, low4));
    const __m256i highs = _mm256_or_si256(_mm256_and_si256(c, high4), _mm256_and_si256(_mm256_srli_epi16(f, 4), low4));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(code + at), lows);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(code + at + 64), highs);
  }
}

void join_planes_scalar(const uint8_t* coarse, const uint8_t* fine, std::size_t plane_bytes, uint8_t* code) {
  for (std::size_t b = 0; b < plane_bytes; b += 64)
    for (std::size_t j = 0; j < 64; ++j) {
      code[2 * b + j] = static_cast<uint8_t>(((coarse[b + j] & 15) << 4) | (fine[b + j] & 15));
      code[2 * b + 64 + j] = static_cast<uint8_t>((coarse[b + j] & 0xF0) | (fine[b + j] >> 4));
    }
}

using ScoreCodes = void (*)(const uint8_t*, std::size_t, std::size_t, const int16_t*, int32_t*);

bool cpu_has_avx2() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
}

bool cpu_has_avx512_vnni() {
  __builtin_cpu_init();
  return cpu_has_avx2() && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vnni");
}

ScoreNibbles choose_score_nibbles() {
  for (const NibbleKernel& k : nibble_kernels())  // the fastest first
    if (k.supported) return k.score;
  return score_nibbles_scalar;
}

}  // namespace

std::vector<NibbleKernel> nibble_kernels() {
  return {{"avx512vnni", cpu_has_avx512_vnni(), score_nibbles_vnni, join_planes_avx2},
          {"avx2", cpu_has_avx2(), score_nibbles_avx2, join_planes_avx2},
          {"scalar", true, score_nibbles_scalar, join_planes_scalar}};
}

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

Sq8Codebook::Sq8Codebook(const std::vector<float>& low, const std::vector<float>& high)
    : low_(low), step_(low.size(), 1.f) {
  for (std::size_t d = 0; d < low.size(); ++d)
    if (high[d] > low[d]) step_[d] = (high[d] - low[d]) / 255.f;
}

void Sq8Codebook::encode(const float* x, uint8_t* coarse, uint8_t* fine) const {
  const std::size_t dim = low_.size(), bytes = plane_bytes();
  std::fill(coarse, coarse + bytes, uint8_t{0});
  std::fill(fine, fine + bytes, uint8_t{0});
  for (std::size_t d = 0; d < dim; ++d) {
    const auto c = static_cast<unsigned>(std::clamp(std::nearbyint((x[d] - low_[d]) / step_[d]), 0.f, 255.f));
    const std::size_t byte = d / 128 * 64 + d % 64;
    const unsigned shift = (d % 128) < 64 ? 0 : 4;
    coarse[byte] = static_cast<uint8_t>(coarse[byte] | ((c >> 4) << shift));
    fine[byte] = static_cast<uint8_t>(fine[byte] | ((c & 15) << shift));
  }
}

// Rounds half away from zero (|x| < 2^31). Not std::nearbyint: without -march that is a libm call
// per value, and a question makes weights for each of the ~30 lists it ranks (5 % of its CPU).
static int32_t round_to_int(double x) { return static_cast<int32_t>(x >= 0 ? x + 0.5 : x - 0.5); }

QueryWeights Sq8Codebook::weights(const float* unit_query) const {
  const std::size_t dim = low_.size();
  std::vector<float> w(dim);
  float largest = 0;
  for (std::size_t d = 0; d < dim; ++d) {
    w[d] = unit_query[d] * step_[d];
    largest = std::max(largest, std::abs(w[d]));
  }
  QueryWeights out;
  out.coarse.assign(stride(), 0);
  out.fine.assign(stride(), 0);
  double at_low = 0, middle = 0;
  for (std::size_t d = 0; d < dim; ++d) {
    at_low += static_cast<double>(unit_query[d]) * low_[d];
    middle += 7.5 * static_cast<double>(w[d]);
  }
  out.fine_offset = static_cast<float>(at_low);
  out.coarse_offset = out.coarse_most = static_cast<float>(at_low + middle);
  if (!(largest > 0)) return out;
  // A high nibble h stands for 16 h (+ 7.5, the same for every code); its weights fill a signed byte.
  const double coarse_scale = 127.0 / (16.0 * largest);
  for (std::size_t d = 0; d < dim; ++d) out.coarse[d] = static_cast<int8_t>(round_to_int(16.0 * w[d] * coarse_scale));
  out.coarse_unit = static_cast<float>(1.0 / coarse_scale);
  int32_t most = 0;
  for (std::size_t d = 0; d < dim; ++d) most += 15 * std::max<int32_t>(out.coarse[d], 0);
  out.coarse_most = out.coarse_offset + out.coarse_unit * static_cast<float>(most);
  // Scaled so that |sum| <= 255 * limit * dim stays below 2^31 (and each pair sum of vpmaddwd too).
  const double limit =
      std::min(8191.0, static_cast<double>(INT_MAX) / (255.0 * static_cast<double>(std::max<std::size_t>(dim, 1))));
  const double fine_scale = limit / largest;
  for (std::size_t d = 0; d < dim; ++d) out.fine[d] = static_cast<int16_t>(round_to_int(w[d] * fine_scale));
  out.fine_unit = static_cast<float>(1.0 / fine_scale);
  return out;
}

void score_nibbles(const uint8_t* planes, std::size_t count, std::size_t plane_bytes, const int8_t* weights,
                   int32_t* out) {
  static const ScoreNibbles kernel = choose_score_nibbles();
  kernel(planes, count, plane_bytes, weights, out);
}

void join_planes(const uint8_t* coarse, const uint8_t* fine, std::size_t plane_bytes, uint8_t* code) {
  static const bool avx2 = cpu_has_avx2();
  (avx2 ? join_planes_avx2 : join_planes_scalar)(coarse, fine, plane_bytes, code);
}

void score_codes(const uint8_t* codes, std::size_t count, std::size_t stride, const int16_t* weights, int32_t* out) {
  static const ScoreCodes kernel = cpu_has_avx2() ? score_codes_avx2 : score_codes_scalar;
  kernel(codes, count, stride, weights, out);
}

}  // namespace slamvdb::ann_codes
