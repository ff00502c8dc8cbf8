#include "slamvdb/core/embedding_kernels.hpp"

#include <cpuid.h>

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "slamvdb/core/half.hpp"

namespace slamvdb::kernels {
namespace {

#define SLAMVDB_AVX2 __attribute__((target("avx2,fma,f16c")))

// ---- portable versions ----
void half_to_float_scalar(const uint16_t* in, float* out, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) out[i] = slamvdb::half_to_float(in[i]);
}
void float_to_half_scalar(const float* in, uint16_t* out, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) out[i] = slamvdb::float_to_half(in[i]);
}
void running_mean_f16_scalar(uint16_t* v, const float* x, float w, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const float old = slamvdb::half_to_float(v[i]);
    v[i] = slamvdb::float_to_half(old + (x[i] - old) * w);
  }
}
float dot_f16_scalar(const uint16_t* v, const float* q, std::size_t n) {
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) s += slamvdb::half_to_float(v[i]) * q[i];
  return s;
}
float squared_norm_f16_scalar(const uint16_t* v, std::size_t n) {
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) s += slamvdb::half_to_float(v[i]) * slamvdb::half_to_float(v[i]);
  return s;
}
void add_scaled_f16_scalar(float* acc, const uint16_t* v, float w, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) acc[i] += w * slamvdb::half_to_float(v[i]);
}
float running_mean_sq_f16_scalar(uint16_t* v, const float* x, float w, std::size_t n) {
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float old = slamvdb::half_to_float(v[i]), d = x[i] - old;
    s += d * d;
    v[i] = slamvdb::float_to_half(old + d * w);
  }
  return s;
}

// ---- AVX2 + F16C + FMA ----
SLAMVDB_AVX2 float hsum(__m256 v) {
  const __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  const __m128 t = _mm_add_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_add_ss(t, _mm_shuffle_ps(t, t, 1)));
}
SLAMVDB_AVX2 __m256 load_half8(const uint16_t* p) {
  return _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}
SLAMVDB_AVX2 void half_to_float_avx2(const uint16_t* in, float* out, std::size_t n) {
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) _mm256_storeu_ps(out + i, load_half8(in + i));
  for (; i < n; ++i) out[i] = _cvtsh_ss(in[i]);
}
SLAMVDB_AVX2 void float_to_half_avx2(const float* in, uint16_t* out, std::size_t n) {
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8)
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                     _mm256_cvtps_ph(_mm256_loadu_ps(in + i), _MM_FROUND_TO_NEAREST_INT));
  for (; i < n; ++i) out[i] = static_cast<uint16_t>(_cvtss_sh(in[i], _MM_FROUND_TO_NEAREST_INT));
}
SLAMVDB_AVX2 void running_mean_f16_avx2(uint16_t* v, const float* x, float w, std::size_t n) {
  const __m256 wv = _mm256_set1_ps(w);
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 old = load_half8(v + i);
    const __m256 upd = _mm256_fmadd_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), old), wv, old);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(v + i), _mm256_cvtps_ph(upd, _MM_FROUND_TO_NEAREST_INT));
  }
  running_mean_f16_scalar(v + i, x + i, w, n - i);
}
SLAMVDB_AVX2 float running_mean_sq_f16_avx2(uint16_t* v, const float* x, float w, std::size_t n) {
  const __m256 wv = _mm256_set1_ps(w);
  __m256 acc = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 old = load_half8(v + i);
    const __m256 d = _mm256_sub_ps(_mm256_loadu_ps(x + i), old);
    acc = _mm256_fmadd_ps(d, d, acc);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(v + i),
                     _mm256_cvtps_ph(_mm256_fmadd_ps(d, wv, old), _MM_FROUND_TO_NEAREST_INT));
  }
  return hsum(acc) + running_mean_sq_f16_scalar(v + i, x + i, w, n - i);
}
SLAMVDB_AVX2 float running_mean_sq_f32_avx2(float* v, const float* x, float w, std::size_t n) {
  const __m256 wv = _mm256_set1_ps(w);
  __m256 acc = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 old = _mm256_loadu_ps(v + i);
    const __m256 d = _mm256_sub_ps(_mm256_loadu_ps(x + i), old);
    acc = _mm256_fmadd_ps(d, d, acc);
    _mm256_storeu_ps(v + i, _mm256_fmadd_ps(d, wv, old));
  }
  float s = hsum(acc);
  for (; i < n; ++i) {
    const float d = x[i] - v[i];
    s += d * d;
    v[i] += d * w;
  }
  return s;
}
SLAMVDB_AVX2 float squared_distance_f16_avx2(const uint16_t* v, const float* x, std::size_t n) {
  __m256 acc = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 d = _mm256_sub_ps(_mm256_loadu_ps(x + i), load_half8(v + i));
    acc = _mm256_fmadd_ps(d, d, acc);
  }
  float s = hsum(acc);
  for (; i < n; ++i) {
    const float d = x[i] - _cvtsh_ss(v[i]);
    s += d * d;
  }
  return s;
}
SLAMVDB_AVX2 void running_mean_f32_avx2(float* v, const float* x, float w, std::size_t n) {
  const __m256 wv = _mm256_set1_ps(w);
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 old = _mm256_loadu_ps(v + i);
    _mm256_storeu_ps(v + i, _mm256_fmadd_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), old), wv, old));
  }
  for (; i < n; ++i) v[i] += (x[i] - v[i]) * w;
}
SLAMVDB_AVX2 float dot_f16_avx2(const uint16_t* v, const float* q, std::size_t n) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    a0 = _mm256_fmadd_ps(load_half8(v + i), _mm256_loadu_ps(q + i), a0);
    a1 = _mm256_fmadd_ps(load_half8(v + i + 8), _mm256_loadu_ps(q + i + 8), a1);
  }
  float s = hsum(_mm256_add_ps(a0, a1));
  for (; i < n; ++i) s += _cvtsh_ss(v[i]) * q[i];
  return s;
}
SLAMVDB_AVX2 float dot_f32_avx2(const float* v, const float* q, std::size_t n) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    a0 = _mm256_fmadd_ps(_mm256_loadu_ps(v + i), _mm256_loadu_ps(q + i), a0);
    a1 = _mm256_fmadd_ps(_mm256_loadu_ps(v + i + 8), _mm256_loadu_ps(q + i + 8), a1);
  }
  float s = hsum(_mm256_add_ps(a0, a1));
  for (; i < n; ++i) s += v[i] * q[i];
  return s;
}
SLAMVDB_AVX2 float squared_norm_f16_avx2(const uint16_t* v, std::size_t n) {
  __m256 a = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 x = load_half8(v + i);
    a = _mm256_fmadd_ps(x, x, a);
  }
  float s = hsum(a);
  for (; i < n; ++i) s += _cvtsh_ss(v[i]) * _cvtsh_ss(v[i]);
  return s;
}
SLAMVDB_AVX2 void add_scaled_f16_avx2(float* acc, const uint16_t* v, float w, std::size_t n) {
  const __m256 wv = _mm256_set1_ps(w);
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8)
    _mm256_storeu_ps(acc + i, _mm256_fmadd_ps(load_half8(v + i), wv, _mm256_loadu_ps(acc + i)));
  for (; i < n; ++i) acc[i] += w * _cvtsh_ss(v[i]);
}

SLAMVDB_AVX2 void add_f16_avx2(float* acc, const uint16_t* v, std::size_t n) {
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) _mm256_storeu_ps(acc + i, _mm256_add_ps(_mm256_loadu_ps(acc + i), load_half8(v + i)));
  for (; i < n; ++i) acc[i] += _cvtsh_ss(v[i]);
}
SLAMVDB_AVX2 void add_f32_avx2(float* acc, const float* v, std::size_t n) {
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8)
    _mm256_storeu_ps(acc + i, _mm256_add_ps(_mm256_loadu_ps(acc + i), _mm256_loadu_ps(v + i)));
  for (; i < n; ++i) acc[i] += v[i];
}

// Four chains of 8 lanes over blocks of 32 values, then 8 at a time into the first, then a scalar
// tail: the same order for both precisions.
SLAMVDB_AVX2 inline __m256 load8(const float* p) { return _mm256_loadu_ps(p); }
SLAMVDB_AVX2 inline __m256 load8(const uint16_t* p) { return load_half8(p); }
inline float widen(float x) { return x; }
inline float widen(uint16_t h) { return slamvdb::half_to_float(h); }
template <typename T>
SLAMVDB_AVX2 float squared_norm_4way_avx2(const T* v, std::size_t n) {
  __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps(), a2 = _mm256_setzero_ps(), a3 = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 32 <= n; i += 32) {
    const __m256 x0 = load8(v + i), x1 = load8(v + i + 8), x2 = load8(v + i + 16), x3 = load8(v + i + 24);
    a0 = _mm256_fmadd_ps(x0, x0, a0);
    a1 = _mm256_fmadd_ps(x1, x1, a1);
    a2 = _mm256_fmadd_ps(x2, x2, a2);
    a3 = _mm256_fmadd_ps(x3, x3, a3);
  }
  for (; i + 8 <= n; i += 8) {
    const __m256 x = load8(v + i);
    a0 = _mm256_fmadd_ps(x, x, a0);
  }
  float s = hsum(_mm256_add_ps(_mm256_add_ps(a0, a1), _mm256_add_ps(a2, a3)));
  for (; i < n; ++i) s += widen(v[i]) * widen(v[i]);
  return s;
}
template <typename T>
float squared_norm_4way_scalar(const T* v, std::size_t n) {
  float a[4] = {0, 0, 0, 0};
  std::size_t i = 0;
  for (; i + 4 <= n; i += 4)
    for (int k = 0; k < 4; ++k) a[k] += widen(v[i + k]) * widen(v[i + k]);
  float s = (a[0] + a[1]) + (a[2] + a[3]);
  for (; i < n; ++i) s += widen(v[i]) * widen(v[i]);
  return s;
}

SLAMVDB_AVX2 void dot_norm_f16_avx2(const uint16_t* v, const float* q, std::size_t n, float* dot, float* norm2) {
  __m256 d0 = _mm256_setzero_ps(), d1 = _mm256_setzero_ps(), s0 = _mm256_setzero_ps(), s1 = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m256 x0 = load_half8(v + i), x1 = load_half8(v + i + 8);
    d0 = _mm256_fmadd_ps(x0, _mm256_loadu_ps(q + i), d0);
    d1 = _mm256_fmadd_ps(x1, _mm256_loadu_ps(q + i + 8), d1);
    s0 = _mm256_fmadd_ps(x0, x0, s0);
    s1 = _mm256_fmadd_ps(x1, x1, s1);
  }
  float d = hsum(_mm256_add_ps(d0, d1)), s = hsum(_mm256_add_ps(s0, s1));
  for (; i < n; ++i) {
    const float x = _cvtsh_ss(v[i]);
    d += x * q[i], s += x * x;
  }
  *dot = d, *norm2 = s;
}

SLAMVDB_AVX2 void dot_norm_pair_f16_avx2(const uint16_t* a, float wa, const uint16_t* b, float wb, const float* q,
                                         std::size_t n, float* dot, float* norm2) {
  const __m256 va = _mm256_set1_ps(wa), vb = _mm256_set1_ps(wb);
  __m256 d0 = _mm256_setzero_ps(), s0 = _mm256_setzero_ps();
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 x = _mm256_fmadd_ps(load_half8(a + i), va, _mm256_mul_ps(load_half8(b + i), vb));
    d0 = _mm256_fmadd_ps(x, _mm256_loadu_ps(q + i), d0);
    s0 = _mm256_fmadd_ps(x, x, s0);
  }
  float d = hsum(d0), s = hsum(s0);
  for (; i < n; ++i) {
    const float x = wa * _cvtsh_ss(a[i]) + wb * _cvtsh_ss(b[i]);
    d += x * q[i], s += x * x;
  }
  *dot = d, *norm2 = s;
}

struct Dispatch {
  bool avx2;
  void (*half_to_float)(const uint16_t*, float*, std::size_t);
  void (*float_to_half)(const float*, uint16_t*, std::size_t);
  void (*running_mean_f16)(uint16_t*, const float*, float, std::size_t);
  float (*dot_f16)(const uint16_t*, const float*, std::size_t);
  float (*squared_norm_f16)(const uint16_t*, std::size_t);
  void (*add_scaled_f16)(float*, const uint16_t*, float, std::size_t);
};

Dispatch choose() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && kernels::cpu_has_f16c())
    return {true, half_to_float_avx2, float_to_half_avx2, running_mean_f16_avx2, dot_f16_avx2, squared_norm_f16_avx2,
            add_scaled_f16_avx2};
  return {false, half_to_float_scalar, float_to_half_scalar, running_mean_f16_scalar, dot_f16_scalar,
          squared_norm_f16_scalar, add_scaled_f16_scalar};
}

const Dispatch& dispatch() {
  static const Dispatch d = choose();
  return d;
}

}  // namespace

bool has_avx2_f16c() { return dispatch().avx2; }

// F16C from CPUID leaf 1 (ECX bit 29): clang 14's __builtin_cpu_supports does not know "f16c".
bool cpu_has_f16c() {
  unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
  return __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & bit_F16C) != 0;
}
void half_to_float(const uint16_t* in, float* out, std::size_t n) { dispatch().half_to_float(in, out, n); }
void float_to_half(const float* in, uint16_t* out, std::size_t n) { dispatch().float_to_half(in, out, n); }

void decode(EmbeddingView v, float* out, std::size_t n) {
  if (v.precision == EmbeddingPrecision::kFloat16) half_to_float(static_cast<const uint16_t*>(v.data), out, n);
  else std::copy_n(static_cast<const float*>(v.data), n, out);
}

void running_mean(float* v, const float* x, float w, std::size_t n) {
  if (dispatch().avx2) return running_mean_f32_avx2(v, x, w, n);
  for (std::size_t i = 0; i < n; ++i) v[i] += (x[i] - v[i]) * w;
}
void running_mean(uint16_t* v, const float* x, float w, std::size_t n) { dispatch().running_mean_f16(v, x, w, n); }

float running_mean_sq(float* v, const float* x, float w, std::size_t n) {
  if (dispatch().avx2) return running_mean_sq_f32_avx2(v, x, w, n);
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float d = x[i] - v[i];
    s += d * d;
    v[i] += d * w;
  }
  return s;
}
float running_mean_sq(uint16_t* v, const float* x, float w, std::size_t n) {
  if (dispatch().avx2) return running_mean_sq_f16_avx2(v, x, w, n);
  return running_mean_sq_f16_scalar(v, x, w, n);
}

float squared_distance(EmbeddingView v, const float* x, std::size_t n) {
  if (v.precision == EmbeddingPrecision::kFloat16 && dispatch().avx2)
    return squared_distance_f16_avx2(static_cast<const uint16_t*>(v.data), x, n);
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const float a = v.precision == EmbeddingPrecision::kFloat16
                        ? slamvdb::half_to_float(static_cast<const uint16_t*>(v.data)[i])
                        : static_cast<const float*>(v.data)[i];
    s += (x[i] - a) * (x[i] - a);
  }
  return s;
}

float squared_distance(EmbeddingView a, EmbeddingView b, std::size_t n) {
  // b decoded in blocks on the stack, each compared with a's slice by the kernel above.
  constexpr std::size_t kBlock = 128;
  float block[kBlock];
  float s = 0;
  const std::size_t a_bytes = bytes_per_value(a.precision), b_bytes = bytes_per_value(b.precision);
  for (std::size_t i = 0; i < n; i += kBlock) {
    const std::size_t m = std::min(kBlock, n - i);
    decode({static_cast<const std::byte*>(b.data) + i * b_bytes, b.precision}, block, m);
    s += squared_distance(EmbeddingView{static_cast<const std::byte*>(a.data) + i * a_bytes, a.precision}, block, m);
  }
  return s;
}

void add_scaled(float* acc, EmbeddingView v, float w, std::size_t n) {
  if (v.precision == EmbeddingPrecision::kFloat16)
    return dispatch().add_scaled_f16(acc, static_cast<const uint16_t*>(v.data), w, n);
  const auto* x = static_cast<const float*>(v.data);
  for (std::size_t i = 0; i < n; ++i) acc[i] += w * x[i];
}

void add(float* acc, EmbeddingView v, std::size_t n) {
  const bool half = v.precision == EmbeddingPrecision::kFloat16;
  if (dispatch().avx2) {
    if (half) return add_f16_avx2(acc, static_cast<const uint16_t*>(v.data), n);
    return add_f32_avx2(acc, static_cast<const float*>(v.data), n);
  }
  if (half) {
    const auto* h = static_cast<const uint16_t*>(v.data);
    for (std::size_t i = 0; i < n; ++i) acc[i] += slamvdb::half_to_float(h[i]);
    return;
  }
  const auto* x = static_cast<const float*>(v.data);
  for (std::size_t i = 0; i < n; ++i) acc[i] += x[i];
}

float squared_norm_4way(EmbeddingView v, std::size_t n) {
  const bool avx2 = dispatch().avx2;
  if (v.precision == EmbeddingPrecision::kFloat16) {
    const auto* h = static_cast<const uint16_t*>(v.data);
    return avx2 ? squared_norm_4way_avx2(h, n) : squared_norm_4way_scalar(h, n);
  }
  const auto* x = static_cast<const float*>(v.data);
  return avx2 ? squared_norm_4way_avx2(x, n) : squared_norm_4way_scalar(x, n);
}

float dot(EmbeddingView v, const float* q, std::size_t n) {
  if (v.precision == EmbeddingPrecision::kFloat16) return dispatch().dot_f16(static_cast<const uint16_t*>(v.data), q, n);
  const auto* x = static_cast<const float*>(v.data);
  if (dispatch().avx2) return dot_f32_avx2(x, q, n);
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) s += x[i] * q[i];
  return s;
}

float squared_norm(EmbeddingView v, std::size_t n) {
  if (v.precision == EmbeddingPrecision::kFloat16)
    return dispatch().squared_norm_f16(static_cast<const uint16_t*>(v.data), n);
  return dot(v, static_cast<const float*>(v.data), n);
}

void dot_and_squared_norm(EmbeddingView v, const float* q, std::size_t n, float* dot, float* norm2) {
  if (v.precision == EmbeddingPrecision::kFloat16 && dispatch().avx2)
    return dot_norm_f16_avx2(static_cast<const uint16_t*>(v.data), q, n, dot, norm2);
  *dot = kernels::dot(v, q, n);
  *norm2 = squared_norm(v, n);  // fp32 (the submap being written, or a shared cell's mean): in cache
}

void dot_and_squared_norm(const CombinedView& v, const float* q, std::size_t n, float* dot, float* norm2) {
  if (v.n == 1) return dot_and_squared_norm(v.view[0], q, n, dot, norm2);
  const EmbeddingView &a = v.view[0], &b = v.view[1];
  if (a.precision == EmbeddingPrecision::kFloat16 && b.precision == EmbeddingPrecision::kFloat16 && dispatch().avx2)
    return dot_norm_pair_f16_avx2(static_cast<const uint16_t*>(a.data), v.weight[0],
                                  static_cast<const uint16_t*>(b.data), v.weight[1], q, n, dot, norm2);
  std::vector<float> x(n, 0.0f);
  add_scaled(x.data(), a, v.weight[0], n);
  add_scaled(x.data(), b, v.weight[1], n);
  dot_and_squared_norm({x.data(), EmbeddingPrecision::kFloat32}, q, n, dot, norm2);
}

bool all_finite(const float* x, std::size_t n) {
  // Summing x * 0 keeps NaN and turns Inf into NaN, in one branch-free pass.
  float s = 0;
  for (std::size_t i = 0; i < n; ++i) s += x[i] * 0.0f;
  return s == 0.0f;
}

}  // namespace slamvdb::kernels
