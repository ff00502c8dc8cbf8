#pragma once
// The few loops over embedding vectors that every hot path runs (fusion's running mean, reading
// fp16 storage, similarity): AVX2 + F16C + FMA when the CPU has them, chosen at run time, and
// portable code otherwise. Runtime dispatch is why these are hand-written: the binary is built
// for any x86-64 (no -march=native) yet must not lose the 8-wide fp16 conversions on the
// machines that have them; Eigen has no fp16 <-> fp32 bulk conversion.
#include <cstddef>
#include <cstdint>

namespace slamvdb {

// Storage precision of embeddings. fp16 halves memory at 512-d (1024 B per voxel instead of 2048 B).
enum class EmbeddingPrecision : uint8_t { kFloat32 = 0, kFloat16 = 1 };

inline std::size_t bytes_per_value(EmbeddingPrecision p) { return p == EmbeddingPrecision::kFloat16 ? 2 : 4; }

// A read-only embedding in its storage precision.
struct EmbeddingView {
  const void* data = nullptr;
  EmbeddingPrecision precision = EmbeddingPrecision::kFloat32;
};

// An embedding given as the weighted sum of one or two stored embeddings (an index cell that two
// submaps share), for readers that combine them in registers instead of writing the mean out.
struct CombinedView {
  uint32_t n = 1;
  EmbeddingView view[2];
  float weight[2] = {1.0f, 0.0f};
};

namespace kernels {

bool has_avx2_f16c();  // what the dispatcher chose (for logs and benchmarks)
bool cpu_has_f16c();   // the CPU converts fp16 in hardware (CPUID; compilers differ in what they detect)

void half_to_float(const uint16_t* in, float* out, std::size_t n);
void float_to_half(const float* in, uint16_t* out, std::size_t n);
// out[i] = value i of `v` decoded to fp32.
void decode(EmbeddingView v, float* out, std::size_t n);

// v <- v + (x - v) * w: Eq. 6.1's running mean with w = 1 / (n + 1), in place.
void running_mean(float* v, const float* x, float w, std::size_t n);
void running_mean(uint16_t* v, const float* x, float w, std::size_t n);
// The same update (bit for bit), returning sum_i (x_i - v_i)^2 of v before it: the squared distance
// that Welford's / West's update of the observations' spread needs, in the same pass.
float running_mean_sq(float* v, const float* x, float w, std::size_t n);
float running_mean_sq(uint16_t* v, const float* x, float w, std::size_t n);
// sum_i (x_i - v_i)^2 with v decoded from its precision.
float squared_distance(EmbeddingView v, const float* x, std::size_t n);
// sum_i (a_i - b_i)^2, both decoded from their precisions (two submaps' entries of one cell).
float squared_distance(EmbeddingView a, EmbeddingView b, std::size_t n);

// acc <- acc + w * v (v decoded from its precision): count-weighted sums for index reads and merges.
void add_scaled(float* acc, EmbeddingView v, float w, std::size_t n);
// acc <- acc + v (v decoded from its precision): fusion's per-voxel sums of feature pixels. fp16
// widens exactly, so an fp16 v gives the sums of its fp32 values, bit for bit.
void add(float* acc, EmbeddingView v, std::size_t n);

// Dot product of a stored embedding with an fp32 vector, and the stored embedding's squared norm.
float dot(EmbeddingView v, const float* q, std::size_t n);
float squared_norm(EmbeddingView v, std::size_t n);
// Both in one pass over v (a similarity search reads every stored embedding once).
void dot_and_squared_norm(EmbeddingView v, const float* q, std::size_t n, float* dot, float* norm2);

// The same for a combined view (two fp16 embeddings on the fast path).
void dot_and_squared_norm(const CombinedView& v, const float* q, std::size_t n, float* dot, float* norm2);

// The squared norm summed in four independent chains (not the order of squared_norm(): the last
// bits differ): for tests of finiteness and zero, where a single chain's FMA latency, not memory,
// would bound fusion. fp16 and fp32 inputs with the same values give the same result.
float squared_norm_4way(EmbeddingView v, std::size_t n);

// True when all n values are finite.
bool all_finite(const float* x, std::size_t n);

}  // namespace kernels
}  // namespace slamvdb
