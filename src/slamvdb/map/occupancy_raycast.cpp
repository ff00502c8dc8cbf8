#include "slamvdb/map/occupancy_raycast.hpp"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <numeric>

namespace slamvdb {

RayCube RayCube::around(const VoxelKey& center, int reach) {
  RayCube cube;
  int lo_block[3], blocks = 0;
  for (int a = 0; a < 3; ++a) {
    lo_block[a] = (center[a] - reach) >> kBlockBits;
    blocks = std::max(blocks, ((center[a] + reach) >> kBlockBits) - lo_block[a] + 1);
  }
  int bits = 1;
  while ((1 << bits) < blocks) ++bits;
  if (bits > 6) return cube;  // side_bits 0: too large
  cube.side_bits = bits;
  cube.lo = VoxelKey(lo_block[0] * kBlockSide, lo_block[1] * kBlockSide, lo_block[2] * kBlockSide);
  return cube;
}

namespace {

// Axis a's coordinate c (relative to the cube) in its bits of the index, and the mask of those bits.
uint32_t dilate(int c, int axis, int side_bits) {
  const auto u = static_cast<uint32_t>(c);
  return ((u & 7u) << (3 * axis)) | ((u >> 3) << (9 + axis * side_bits));
}
uint32_t axis_mask(int axis, int side_bits) {
  return (7u << (3 * axis)) | (((1u << side_bits) - 1) << (9 + axis * side_bits));
}

// Crossing parameters (0 at `from`, 1 at `to`) in fixed point with 29 fractional bits. Parameters
// beyond 2 are clamped to 2: a segment ends at 1, so they are never the smallest while the ray still
// has steps left, and a step then adds at most 2, so no sum overflows.
constexpr double kFixedOne = 0x1p29;
inline int32_t to_fixed(double t) { return static_cast<int32_t>(std::min(t, 2.0) * kFixedOne + 0.5); }

// What every ray from one origin shares.
struct Origin {
  double f[3];     // `from`
  int k[3];        // its voxel
  uint32_t start;  // that voxel's bit index
  uint32_t mask[3];
  uint32_t spare;  // the first bit of the extra brick, where lanes write what is not a voxel
  Origin(const RayCube& cube, const Vec3d& from) {
    start = 0;
    for (int a = 0; a < 3; ++a) {
      f[a] = from[a];
      k[a] = static_cast<int>(std::floor(from[a]));
      start |= dilate(k[a] - cube.lo[a], a, cube.side_bits);
      mask[a] = axis_mask(a, cube.side_bits);
    }
    spare = static_cast<uint32_t>(cube.num_bricks()) << 9;
  }
};

// One ray's stepping state: as traverse_voxels sets it up (same double expressions), then fixed
// point. Stepping axis a adds inc[a] to the dilated coordinate: (c - mask) & mask is c + 1 in the
// mask's bits, (c - 1) & mask is c - 1.
struct Ray {
  int32_t t[3], d[3];
  uint32_t inc[3];
  int32_t steps;  // voxels to visit: the Manhattan distance between the end voxels
};

inline Ray setup(const Origin& o, const Vec3d& to) {
  Ray r;
  r.steps = 0;
  for (int a = 0; a < 3; ++a) {
    const double f = o.f[a], d = to[a] - f;
    r.steps += std::abs(static_cast<int>(std::floor(to[a])) - o.k[a]);
    double t_max, t_delta;
    if (d > 0) {
      t_delta = 1.0 / d, t_max = (o.k[a] + 1 - f) * t_delta, r.inc[a] = 0u - o.mask[a];
    } else if (d < 0) {
      t_delta = -1.0 / d, t_max = (f - o.k[a]) * t_delta, r.inc[a] = ~0u;
    } else {
      t_delta = t_max = 2.0, r.inc[a] = 0;
    }
    r.t[a] = to_fixed(t_max);
    r.d[a] = to_fixed(t_delta);
  }
  return r;
}

inline void mark(uint64_t* words, uint32_t bit) { words[bit >> 6] |= uint64_t{1} << (bit & 63); }

// Same stepping rule as traverse_voxels: x when tx < ty and tx < tz, else y when ty < tz, else z.
void mark_ray(const Origin& o, const Ray& r, uint64_t* words) {
  int32_t tx = r.t[0], ty = r.t[1], tz = r.t[2];
  uint32_t x = o.start & o.mask[0], y = o.start & o.mask[1], z = o.start & o.mask[2];
  for (int n = r.steps; n > 0; --n) {
    mark(words, x | y | z);
    if (tx < ty) {
      if (tx < tz) x = (x + r.inc[0]) & o.mask[0], tx += r.d[0];
      else z = (z + r.inc[2]) & o.mask[2], tz += r.d[2];
    } else {
      if (ty < tz) y = (y + r.inc[1]) & o.mask[1], ty += r.d[1];
      else z = (z + r.inc[2]) & o.mask[2], tz += r.d[2];
    }
  }
}

#define SLAMVDB_AVX2 __attribute__((target("avx2")))

// setup() for eight rays, four per register of doubles: the same operations in the same order
// (no FMA), so the same bits. 1 / |d| is -1 / d exactly when d < 0.
SLAMVDB_AVX2 void setup8(const Origin& o, const Vec3d* to, __m256i* t, __m256i* d, __m256i* inc, __m256i& steps) {
  const __m256d zero = _mm256_setzero_pd(), two = _mm256_set1_pd(2.0), one = _mm256_set1_pd(1.0),
                scale = _mm256_set1_pd(kFixedOne), half = _mm256_set1_pd(0.5),
                sign = _mm256_set1_pd(-0.0);
  steps = _mm256_setzero_si256();
  auto fixed = [&](__m256d v) SLAMVDB_AVX2 {
    return _mm256_cvttpd_epi32(_mm256_add_pd(_mm256_mul_pd(_mm256_min_pd(v, two), scale), half));
  };
  for (int a = 0; a < 3; ++a) {
    const __m256d f = _mm256_set1_pd(o.f[a]), up = _mm256_set1_pd(o.k[a] + 1 - o.f[a]),
                  down = _mm256_set1_pd(o.f[a] - o.k[a]);
    __m128i tq[2], dq[2], eq[2];
    __m256d pos[2], neg[2];
    for (int h = 0; h < 2; ++h) {
      const Vec3d* r = to + 4 * h;
      const __m256d e = _mm256_setr_pd(r[0][a], r[1][a], r[2][a], r[3][a]);
      const __m256d dd = _mm256_sub_pd(e, f);
      pos[h] = _mm256_cmp_pd(dd, zero, _CMP_GT_OQ), neg[h] = _mm256_cmp_pd(dd, zero, _CMP_LT_OQ);
      const __m256d moving = _mm256_or_pd(pos[h], neg[h]);
      const __m256d td = _mm256_div_pd(one, _mm256_andnot_pd(sign, dd));
      const __m256d tm = _mm256_mul_pd(_mm256_blendv_pd(down, up, pos[h]), td);
      tq[h] = fixed(_mm256_blendv_pd(two, tm, moving));
      dq[h] = fixed(_mm256_blendv_pd(two, td, moving));
      eq[h] = _mm256_cvttpd_epi32(_mm256_floor_pd(e));
    }
    t[a] = _mm256_set_m128i(tq[1], tq[0]);
    d[a] = _mm256_set_m128i(dq[1], dq[0]);
    const __m256i e = _mm256_set_m128i(eq[1], eq[0]);
    steps = _mm256_add_epi32(steps, _mm256_abs_epi32(_mm256_sub_epi32(e, _mm256_set1_epi32(o.k[a]))));
    // Lane masks of the direction's sign, from the 64-bit comparison masks.
    const __m256i perm = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
    auto narrow = [&](__m256d m0, __m256d m1) SLAMVDB_AVX2 {
      const __m256i lo = _mm256_permutevar8x32_epi32(_mm256_castpd_si256(m0), perm),
                    hi = _mm256_permutevar8x32_epi32(_mm256_castpd_si256(m1), perm);
      return _mm256_permute2x128_si256(lo, hi, 0x20);
    };
    const __m256i is_pos = narrow(pos[0], pos[1]), is_neg = narrow(neg[0], neg[1]);
    inc[a] = _mm256_or_si256(_mm256_and_si256(is_pos, _mm256_set1_epi32(static_cast<int>(0u - o.mask[a]))), is_neg);
  }
}

// Sets the bits of eight lanes' voxels (bit indices in `idx`). A read-modify-write of a word waits
// for the previous one to the same word, so eight lanes in one word (near the sensor, neighbouring
// rays all are) are ORed together and written once; finished lanes write spare words of their own
// for the same reason. (Merging every run of lanes in one word, with a carry between lanes, was
// slower on the real scan: more work per lane than the waits it saves.)
SLAMVDB_AVX2 inline void mark8(uint64_t* words, __m256i idx) {
  alignas(32) uint32_t bit[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(bit), idx);
  const __m256i word = _mm256_srli_epi32(idx, 6);
  const __m256i same_as_first = _mm256_cmpeq_epi32(word, _mm256_permutevar8x32_epi32(word, _mm256_setzero_si256()));
  if (_mm256_movemask_ps(_mm256_castsi256_ps(same_as_first)) == 0xff) {
    uint64_t m = 0;
    for (int l = 0; l < 8; ++l) m |= uint64_t{1} << (bit[l] & 63);
    words[bit[0] >> 6] |= m;
    return;
  }
  // One lane after the other: left to itself the compiler computes all eight addresses and masks
  // first and spills them to the stack (the barrier is 8-9% of a scan's integration).
  for (int l = 0; l < 8; ++l) {
    mark(words, bit[l]);
    asm volatile("" ::: "memory");
  }
}

// Eight rays in the lanes of AVX2 registers, stepped together until the longest has ended (rays
// come grouped by direction, so neighbours have similar lengths); lanes whose ray has ended write
// to their spare bit. The axis choice is a pair of comparisons and masks instead of branches.
SLAMVDB_AVX2 void mark_segments_avx2(const Origin& o, const Vec3d* rays, std::span<const uint32_t> to, uint64_t* words) {
  const __m256i mx = _mm256_set1_epi32(static_cast<int>(o.mask[0])), my = _mm256_set1_epi32(static_cast<int>(o.mask[1])),
                mz = _mm256_set1_epi32(static_cast<int>(o.mask[2]));
  // Lane l's spare: word l of the extra brick.
  const __m256i spare = _mm256_add_epi32(_mm256_set1_epi32(static_cast<int>(o.spare)), _mm256_setr_epi32(0, 64, 128, 192, 256, 320, 384, 448));
  const __m256i one = _mm256_set1_epi32(1), lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  for (std::size_t first = 0; first < to.size(); first += 8) {
    const std::size_t count = std::min<std::size_t>(8, to.size() - first);
    Vec3d group[8];  // the last group padded with its first ray, then given no steps
    for (std::size_t l = 0; l < 8; ++l) group[l] = rays[to[first + (l < count ? l : 0)]];
    // The next group's rays are scattered over megabytes: fetched while this one is cast.
    for (std::size_t l = first + 8; l < std::min(first + 16, to.size()); ++l) __builtin_prefetch(&rays[to[l]]);
    __m256i t[3], d[3], inc[3], left;
    setup8(o, group, t, d, inc, left);
    if (count < 8) left = _mm256_and_si256(left, _mm256_cmpgt_epi32(_mm256_set1_epi32(static_cast<int>(count)), lanes));
    alignas(32) int32_t steps[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(steps), left);
    const int longest = *std::max_element(steps, steps + 8);
    __m256i tx = t[0], ty = t[1], tz = t[2];
    const __m256i dx = d[0], dy = d[1], dz = d[2], ix = inc[0], iy = inc[1], iz = inc[2];
    __m256i x = _mm256_set1_epi32(static_cast<int>(o.start & o.mask[0])),
            y = _mm256_set1_epi32(static_cast<int>(o.start & o.mask[1])),
            z = _mm256_set1_epi32(static_cast<int>(o.start & o.mask[2]));
    for (int n = 0; n < longest; ++n) {
      const __m256i active = _mm256_cmpgt_epi32(left, _mm256_setzero_si256());
      left = _mm256_sub_epi32(left, one);
      mark8(words, _mm256_blendv_epi8(spare, _mm256_or_si256(_mm256_or_si256(x, y), z), active));
      const __m256i x_first = _mm256_cmpgt_epi32(ty, tx);         // tx < ty
      const __m256i t_min = _mm256_blendv_epi8(ty, tx, x_first);  // the smaller of tx, ty
      const __m256i not_z = _mm256_cmpgt_epi32(tz, t_min);
      const __m256i sx = _mm256_and_si256(x_first, not_z), sy = _mm256_andnot_si256(x_first, not_z);
      tx = _mm256_add_epi32(tx, _mm256_and_si256(dx, sx));
      ty = _mm256_add_epi32(ty, _mm256_and_si256(dy, sy));
      tz = _mm256_add_epi32(tz, _mm256_andnot_si256(not_z, dz));
      x = _mm256_and_si256(_mm256_add_epi32(x, _mm256_and_si256(ix, sx)), mx);
      y = _mm256_and_si256(_mm256_add_epi32(y, _mm256_and_si256(iy, sy)), my);
      z = _mm256_and_si256(_mm256_add_epi32(z, _mm256_andnot_si256(not_z, iz)), mz);
    }
  }
}

}  // namespace

void mark_segments_scalar(const RayCube& cube, const Vec3d& from, const Vec3d* rays, std::span<const uint32_t> to,
                          uint64_t* words) {
  const Origin o(cube, from);
  for (const uint32_t i : to) mark_ray(o, setup(o, rays[i]), words);
}

void mark_segments(const RayCube& cube, const Vec3d& from, const Vec3d* rays, std::span<const uint32_t> to,
                   uint64_t* words) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2) mark_segments_avx2(Origin(cube, from), rays, to, words);
  else mark_segments_scalar(cube, from, rays, to, words);
}

// Rays are cast grouped by direction (cube-map tiles) so that neighbouring rays mark
// neighbouring words, and by length within a tile: they are cast eight at a time, for as many
// steps as the longest of the eight needs. Two stable counting sorts of ray indices; the casting
// reads the rays through them (moving the 24-byte rays cost more than the sorts).
std::vector<uint32_t> casting_order(const std::vector<uint32_t>& sort_keys) {
  constexpr uint32_t kBuckets = 1024;
  std::vector<uint32_t> first(kBuckets + 1, 0);
  for (const uint32_t k : sort_keys)
    if (k != kNotCast) ++first[(k & (kBuckets - 1)) + 1];
  std::partial_sum(first.begin(), first.end(), first.begin());
  const uint32_t num_cast = first[kBuckets];
  std::unique_ptr<uint32_t[]> by_length(new uint32_t[num_cast]);  // not zeroed: every element is written
  std::vector<uint32_t> next(kNumRayTiles + 1, 0);                // counted during the first sort
  for (uint32_t i = 0; i < sort_keys.size(); ++i)
    if (const uint32_t k = sort_keys[i]; k != kNotCast) {
      by_length[first[k & (kBuckets - 1)]++] = i;
      ++next[(k >> 10) + 1];
    }
  std::partial_sum(next.begin(), next.end(), next.begin());
  std::vector<uint32_t> order(num_cast);
  for (uint32_t j = 0; j < num_cast; ++j) {
    const uint32_t i = by_length[j];
    order[next[sort_keys[i] >> 10]++] = i;
  }
  return order;
}

namespace {
// At most 64 MB kept: enough for two threads' bitmaps at a 64-block cube, or many at the defaults.
constexpr std::size_t kMaxPooledWords = std::size_t{8} << 20;
struct Pool {
  std::mutex mutex;
  std::vector<std::vector<uint64_t>> spare;
  std::size_t words = 0;  // in `spare`
};
Pool& pool() {
  static Pool p;
  return p;
}
}  // namespace

PooledBitmap::PooledBitmap(std::size_t words) {
  {
    Pool& p = pool();
    std::lock_guard lock(p.mutex);
    for (auto it = p.spare.begin(); it != p.spare.end(); ++it)
      if (it->size() == words) {
        words_ = std::move(*it);
        p.spare.erase(it);
        p.words -= words;
        return;
      }
  }
  words_.assign(words, 0);
}

PooledBitmap::~PooledBitmap() {
  if (!clear_ || words_.empty()) return;
  Pool& p = pool();
  std::lock_guard lock(p.mutex);
  if (p.words + words_.size() > kMaxPooledWords) return;
  p.words += words_.size();
  p.spare.push_back(std::move(words_));
}

}  // namespace slamvdb
