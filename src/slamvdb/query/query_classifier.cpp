#include "slamvdb/query/query_classifier.hpp"

#include <fmt/format.h>
#include <immintrin.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

// Rows per kernel call: the dot products of a chunk (kChunk x classes floats) stay in L1.
constexpr std::size_t kChunk = 256;
constexpr std::size_t kParallelGrain = 2048;

using RowBlock = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
using DotBlock = Eigen::Map<Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;

// The portable kernel: one matrix product per chunk (embeddings x queries^T) and the rows'
// squared norms.
void dots_eigen(const float* x, std::size_t rows, const QueryMatrix& q, float* dots, float* norm2) {
  const RowBlock block(x, static_cast<Eigen::Index>(rows), q.cols());
  DotBlock(dots, static_cast<Eigen::Index>(rows), q.rows()).noalias() = block * q.transpose();
  Eigen::Map<Eigen::VectorXf>(norm2, static_cast<Eigen::Index>(rows)) = block.rowwise().squaredNorm();
}

// The AVX2 + FMA kernel. Why by hand: the binary is built for any x86-64 (no -march=native), so
// Eigen compiles to SSE2, which measured 3x slower than this on the 1 M x 512 x 6 benchmark; and
// Eigen cannot be compiled twice with different instruction sets in one program without breaking
// the one-definition rule. This reads each embedding once and accumulates up to six dot products
// and the squared norm in registers (the queries stay in L1).
#define SLAMVDB_AVX2 __attribute__((target("avx2,fma")))

SLAMVDB_AVX2 inline float hsum(__m256 v) {
  const __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  const __m128 t = _mm_add_ps(s, _mm_movehl_ps(s, s));
  return _mm_cvtss_f32(_mm_add_ss(t, _mm_shuffle_ps(t, t, 1)));
}

template <int NQ, bool kNorm>
SLAMVDB_AVX2 void dot_block(const float* x, const float* q, int dim, float* out, float* norm2) {
  constexpr int kAcc = NQ + (kNorm ? 1 : 0);
  __m256 acc[kAcc];
  for (int k = 0; k < kAcc; ++k) acc[k] = _mm256_setzero_ps();
  int d = 0;
  for (; d + 8 <= dim; d += 8) {
    const __m256 v = _mm256_loadu_ps(x + d);
    for (int k = 0; k < NQ; ++k)
      acc[k] = _mm256_fmadd_ps(v, _mm256_loadu_ps(q + static_cast<std::size_t>(k) * dim + d), acc[k]);
    if constexpr (kNorm) acc[NQ] = _mm256_fmadd_ps(v, v, acc[NQ]);
  }
  float tail[kAcc] = {};
  for (; d < dim; ++d) {
    for (int k = 0; k < NQ; ++k) tail[k] += x[d] * q[static_cast<std::size_t>(k) * dim + d];
    if constexpr (kNorm) tail[NQ] += x[d] * x[d];
  }
  for (int k = 0; k < NQ; ++k) out[k] = hsum(acc[k]) + tail[k];
  if constexpr (kNorm) *norm2 = hsum(acc[NQ]) + tail[NQ];
}

template <bool kNorm>
SLAMVDB_AVX2 void dot_block_n(int nq, const float* x, const float* q, int dim, float* out, float* norm2) {
  switch (nq) {
    case 1: return dot_block<1, kNorm>(x, q, dim, out, norm2);
    case 2: return dot_block<2, kNorm>(x, q, dim, out, norm2);
    case 3: return dot_block<3, kNorm>(x, q, dim, out, norm2);
    case 4: return dot_block<4, kNorm>(x, q, dim, out, norm2);
    case 5: return dot_block<5, kNorm>(x, q, dim, out, norm2);
    default: return dot_block<6, kNorm>(x, q, dim, out, norm2);
  }
}

SLAMVDB_AVX2 void dots_avx2(const float* x, std::size_t rows, const QueryMatrix& q, float* dots, float* norm2) {
  const int n = static_cast<int>(q.rows()), dim = static_cast<int>(q.cols());
  for (std::size_t r = 0; r < rows; ++r) {
    const float* row = x + r * dim;
    float* out = dots + r * n;
    for (int k0 = 0; k0 < n; k0 += 6) {  // blocks of six queries; the row stays in L1 between blocks
      const int nq = std::min(6, n - k0);
      const float* qk = q.data() + static_cast<std::size_t>(k0) * dim;
      if (k0 == 0) dot_block_n<true>(nq, row, qk, dim, out, norm2 + r);
      else dot_block_n<false>(nq, row, qk, dim, out + k0, nullptr);
    }
  }
}

// The same for rows anywhere in memory in their storage precision (the map's fp16 entries are
// read where they are stored, with no decoded copy): F16C converts eight values per load.
#define SLAMVDB_AVX2_F16C __attribute__((target("avx2,fma,f16c")))

template <int NQ, bool kHalf>
SLAMVDB_AVX2_F16C void dot_block_view(const void* xv, const float* q, int dim, float* out, float* norm2) {
  __m256 acc[NQ + 1];
  for (int k = 0; k <= NQ; ++k) acc[k] = _mm256_setzero_ps();
  const auto* xh = static_cast<const uint16_t*>(xv);
  const auto* xf = static_cast<const float*>(xv);
  int d = 0;
  for (; d + 8 <= dim; d += 8) {
    const __m256 v = kHalf ? _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(xh + d)))
                           : _mm256_loadu_ps(xf + d);
    for (int k = 0; k < NQ; ++k)
      acc[k] = _mm256_fmadd_ps(v, _mm256_loadu_ps(q + static_cast<std::size_t>(k) * dim + d), acc[k]);
    acc[NQ] = _mm256_fmadd_ps(v, v, acc[NQ]);
  }
  float tail[NQ + 1] = {};
  for (; d < dim; ++d) {
    const float x = kHalf ? _cvtsh_ss(xh[d]) : xf[d];
    for (int k = 0; k < NQ; ++k) tail[k] += x * q[static_cast<std::size_t>(k) * dim + d];
    tail[NQ] += x * x;
  }
  for (int k = 0; k < NQ; ++k) out[k] = hsum(acc[k]) + tail[k];
  *norm2 = hsum(acc[NQ]) + tail[NQ];
}

// Two fp16 rows combined as wa * a + wb * b in registers (an index cell shared by two submaps).
template <int NQ>
SLAMVDB_AVX2_F16C void dot_block_pair(const uint16_t* a, float wa, const uint16_t* b, float wb, const float* q, int dim,
                                      float* out, float* norm2) {
  __m256 acc[NQ + 1];
  for (int k = 0; k <= NQ; ++k) acc[k] = _mm256_setzero_ps();
  const __m256 va = _mm256_set1_ps(wa), vb = _mm256_set1_ps(wb);
  int d = 0;
  for (; d + 8 <= dim; d += 8) {
    const __m256 x = _mm256_fmadd_ps(_mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + d))), va,
                                     _mm256_mul_ps(_mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(b + d))), vb));
    for (int k = 0; k < NQ; ++k)
      acc[k] = _mm256_fmadd_ps(x, _mm256_loadu_ps(q + static_cast<std::size_t>(k) * dim + d), acc[k]);
    acc[NQ] = _mm256_fmadd_ps(x, x, acc[NQ]);
  }
  float tail[NQ + 1] = {};
  for (; d < dim; ++d) {
    const float x = wa * _cvtsh_ss(a[d]) + wb * _cvtsh_ss(b[d]);
    for (int k = 0; k < NQ; ++k) tail[k] += x * q[static_cast<std::size_t>(k) * dim + d];
    tail[NQ] += x * x;
  }
  for (int k = 0; k < NQ; ++k) out[k] = hsum(acc[k]) + tail[k];
  *norm2 = hsum(acc[NQ]) + tail[NQ];
}

SLAMVDB_AVX2_F16C void dots_pair_avx2(const CombinedView& v, const QueryMatrix& q, float* out, float* norm2) {
  const int n = static_cast<int>(q.rows()), dim = static_cast<int>(q.cols());
  const auto* a = static_cast<const uint16_t*>(v.view[0].data);
  const auto* b = static_cast<const uint16_t*>(v.view[1].data);
  float ignored;
  for (int k0 = 0; k0 < n; k0 += 6) {
    const int nq = std::min(6, n - k0);
    const float* qk = q.data() + static_cast<std::size_t>(k0) * dim;
    float* o = out + k0;
    float* n2 = k0 == 0 ? norm2 : &ignored;
    switch (nq) {
      case 1: dot_block_pair<1>(a, v.weight[0], b, v.weight[1], qk, dim, o, n2); break;
      case 2: dot_block_pair<2>(a, v.weight[0], b, v.weight[1], qk, dim, o, n2); break;
      case 3: dot_block_pair<3>(a, v.weight[0], b, v.weight[1], qk, dim, o, n2); break;
      case 4: dot_block_pair<4>(a, v.weight[0], b, v.weight[1], qk, dim, o, n2); break;
      case 5: dot_block_pair<5>(a, v.weight[0], b, v.weight[1], qk, dim, o, n2); break;
      default: dot_block_pair<6>(a, v.weight[0], b, v.weight[1], qk, dim, o, n2); break;
    }
  }
}

template <bool kHalf>
SLAMVDB_AVX2_F16C void dots_view_avx2(const EmbeddingView& v, const QueryMatrix& q, float* out, float* norm2) {
  const int n = static_cast<int>(q.rows()), dim = static_cast<int>(q.cols());
  float ignored;
  for (int k0 = 0; k0 < n; k0 += 6) {  // blocks of six queries; the row stays in L1 between blocks
    const int nq = std::min(6, n - k0);
    const float* qk = q.data() + static_cast<std::size_t>(k0) * dim;
    float* o = out + k0;
    float* n2 = k0 == 0 ? norm2 : &ignored;
    switch (nq) {
      case 1: dot_block_view<1, kHalf>(v.data, qk, dim, o, n2); break;
      case 2: dot_block_view<2, kHalf>(v.data, qk, dim, o, n2); break;
      case 3: dot_block_view<3, kHalf>(v.data, qk, dim, o, n2); break;
      case 4: dot_block_view<4, kHalf>(v.data, qk, dim, o, n2); break;
      case 5: dot_block_view<5, kHalf>(v.data, qk, dim, o, n2); break;
      default: dot_block_view<6, kHalf>(v.data, qk, dim, o, n2); break;
    }
  }
}

bool cpu_has_f16c() { return kernels::cpu_has_f16c(); }

bool cpu_has_avx2_fma() {
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
}

}  // namespace

QueryClassifier::QueryClassifier(const QuerySet& queries, ClassifyOptions options) {
  queries.validate("query set '" + queries.model_id + "'");
  // Only the classes that can be the answer enter the kernel: under the void rule a void class's
  // similarity decides nothing, and leaving it out saves one of the ~7 dot products per embedding.
  num_classes_ = queries.size();
  for (int k = 0; k < queries.size(); ++k)
    if (!(options.void_to_second_best && queries.is_void(k))) class_of_row_.push_back(k);
  queries_.resize(static_cast<Eigen::Index>(class_of_row_.size()), queries.dim());
  for (std::size_t r = 0; r < class_of_row_.size(); ++r)
    queries_.row(static_cast<Eigen::Index>(r)) =
        unit_vector({queries.vectors.row(class_of_row_[r]).data(), static_cast<std::size_t>(queries.dim())})
            .value()  // validate() refused zero and non-finite rows
            .transpose();
  use_avx2_ = !options.portable_kernel && cpu_has_avx2_fma();
  use_f16c_ = use_avx2_ && cpu_has_f16c();
}

void QueryClassifier::classify_chunk(const float* x, std::size_t rows, QueryMatch* out, float* d,
                                     float* norm2) const {
  if (use_avx2_) dots_avx2(x, rows, queries_, d, norm2);
  else dots_eigen(x, rows, queries_, d, norm2);
  decide(d, norm2, rows, out);
}

void QueryClassifier::classify_views(const EmbeddingView* rows, std::size_t count, QueryMatch* out) const {
  std::vector<CombinedView> combined(count);
  for (std::size_t r = 0; r < count; ++r) combined[r].view[0] = rows[r];
  classify_combined(combined.data(), count, out);
}

void QueryClassifier::classify_combined(const CombinedView* rows, std::size_t count, QueryMatch* out) const {
  const int n = static_cast<int>(queries_.rows());
  const auto dim = static_cast<std::size_t>(this->dim());
  std::vector<float> dots(count * n), norm2(count), row;
  for (std::size_t r = 0; r < count; ++r) {
    const CombinedView& v = rows[r];
    float* d = dots.data() + r * n;
    const bool fp16 = v.view[0].precision == EmbeddingPrecision::kFloat16;
    if (use_f16c_ && v.n == 1) {
      if (fp16) dots_view_avx2<true>(v.view[0], queries_, d, &norm2[r]);
      else dots_view_avx2<false>(v.view[0], queries_, d, &norm2[r]);
    } else if (use_f16c_ && v.n == 2 && fp16 && v.view[1].precision == EmbeddingPrecision::kFloat16) {
      dots_pair_avx2(v, queries_, d, &norm2[r]);
    } else {  // the portable path: the row (or the weighted sum) decoded to fp32
      row.assign(dim, 0.0f);
      for (uint32_t k = 0; k < v.n; ++k) kernels::add_scaled(row.data(), v.view[k], v.weight[k], dim);
      dots_eigen(row.data(), 1, queries_, d, &norm2[r]);
    }
  }
  decide(dots.data(), norm2.data(), count, out);
}

void QueryClassifier::decide(const float* d, const float* norm2, std::size_t rows, QueryMatch* out) const {
  const int n = static_cast<int>(queries_.rows());
  for (std::size_t r = 0; r < rows; ++r) {
    QueryMatch& m = out[r];
    // Zero, NaN, infinite (or overflowing) embeddings have no direction: no class, no NaN score.
    if (!(norm2[r] > 0.f) || !std::isfinite(norm2[r])) {
      m = QueryMatch{};
      continue;
    }
    const float inv = 1.f / std::sqrt(norm2[r]);
    const float* s = d + r * n;
    int best = -1;
    float best_score = -std::numeric_limits<float>::infinity(), second = best_score;
    for (int k = 0; k < n; ++k) {
      if (s[k] > best_score) {
        second = best_score;
        best_score = s[k];
        best = k;
      } else if (s[k] > second) {
        second = s[k];
      }
    }
    m.class_index = best < 0 ? kNoClass : class_of_row_[best];
    m.score = best_score * inv;
    m.margin = std::isinf(second) ? std::numeric_limits<float>::infinity() : (best_score - second) * inv;
  }
}

void QueryClassifier::classify(const float* embeddings, std::size_t rows, QueryMatch* out) const {
  const auto run = [&](std::size_t begin, std::size_t end) {
    std::vector<float> dots(kChunk * queries_.rows()), norm2(kChunk);
    for (std::size_t r = begin; r < end; r += kChunk) {
      const std::size_t count = std::min(kChunk, end - r);
      classify_chunk(embeddings + r * dim(), count, out + r, dots.data(), norm2.data());
    }
  };
  if (rows <= kParallelGrain) {
    run(0, rows);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows, kParallelGrain),
                    [&](const tbb::blocked_range<std::size_t>& range) { run(range.begin(), range.end()); });
}

std::vector<QueryMatch> QueryClassifier::classify(std::span<const float> embeddings) const {
  if (embeddings.size() % dim() != 0)
    throw Error(fmt::format("{} values are not whole {}-d embeddings", embeddings.size(), dim()));
  std::vector<QueryMatch> out(embeddings.size() / dim());
  classify(embeddings.data(), out.size(), out.data());
  return out;
}

std::vector<QueryMatch> classify_embeddings(std::span<const float> embeddings, const QuerySet& queries,
                                            const ClassifyOptions& options) {
  return QueryClassifier(queries, options).classify(embeddings);
}

}  // namespace slamvdb
