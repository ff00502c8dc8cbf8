#include "slamvdb/map/occupancy_rays.hpp"

#include <immintrin.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

namespace slamvdb {
namespace {

inline void set_bit(uint64_t* words, uint32_t bit) { words[bit >> 6] |= uint64_t{1} << (bit & 63); }

// Where a ray without a hit marks (the spare brick of the hit bitmap).
inline uint32_t no_hit_bit(const RayCube& cube) { return static_cast<uint32_t>(cube.num_bricks()) << 9; }

// One point. The AVX2 path below performs the same operations in the same order (no FMA), so both
// give the same bits; it hands every rare case (dropped points, hits outside the cube) to this.
void prepare_one(const RaySetup& s, const Vec3f& p, Vec3d& to_out, uint32_t& key_out, uint64_t* hit_words,
                 PreparedRays& out) {
  const double x = p.x(), y = p.y(), z = p.z();
  // Infinite or NaN exactly when a coordinate is (squares of floats do not overflow a double).
  const double range2 = x * x + y * y + z * z;
  if (!(range2 > 0.0 && range2 >= s.min_range * s.min_range && range2 <= std::numeric_limits<double>::max())) {
    ++(!std::isfinite(range2) ? out.nonfinite : range2 == 0.0 ? out.no_return : out.too_close);
    key_out = kNotCast;
    return;
  }
  const Eigen::Matrix3d& R = s.R;
  const bool hit = range2 <= s.max_range * s.max_range;
  const bool cut = !(hit && range2 <= s.clear_range * s.clear_range);
  // R p scaled (by 1 unless the ray is cut short) instead of a unit direction times a length.
  const double rp[3] = {(R(0, 0) * x + R(0, 1) * y) + R(0, 2) * z, (R(1, 0) * x + R(1, 1) * y) + R(1, 2) * z,
                        (R(2, 0) * x + R(2, 1) * y) + R(2, 2) * z};
  double end_scale = 1.0, to_scale = 1.0;
  if (cut) {
    const double range = std::sqrt(range2), length = hit ? range : s.max_range;
    end_scale = length / range;
    to_scale = std::min(length, s.clear_range) / range;
  }
  Vec3d end, to;
  for (int a = 0; a < 3; ++a) {
    end[a] = (s.origin[a] + rp[a] * end_scale) * s.inv_voxel_size;
    to[a] = (s.origin[a] + rp[a] * to_scale) * s.inv_voxel_size;
  }
  // Both ends of what the ray touches must be representable: the hit and the end of the cleared
  // segment.
  if (!in_grid_extent(end) || !in_grid_extent(to)) {
    ++out.out_of_extent;
    key_out = kNotCast;
    return;
  }
  const VoxelKey to_key = key_of_point<VoxelKey>(to, 1.0);
  const auto steps = static_cast<uint32_t>((to_key - s.from_key).cwiseAbs().sum());
  to_out = to;
  key_out = ray_tile_of(Vec3f(static_cast<float>(rp[0]), static_cast<float>(rp[1]), static_cast<float>(rp[2]))) << 10 |
            std::min(steps, 1023u);
  out.beyond_max_range += !hit;
  // The hit's voxel; a ray without a hit keeps to_key here, which adds nothing to the box.
  const VoxelKey k = hit && cut ? key_of_point<VoxelKey>(end, 1.0) : to_key;
  out.lo = out.lo.cwiseMin(to_key).cwiseMin(k), out.hi = out.hi.cwiseMax(to_key).cwiseMax(k);
  if (s.cube.side_bits == 0) {
    if (hit) out.hits_outside.push_back(k);
  } else if (!hit) {
    set_bit(hit_words, no_hit_bit(s.cube));
  } else if (s.cube.contains(k)) {
    set_bit(hit_words, s.cube.bit_of(k));
  } else {
    out.hits_outside.push_back(k);
  }
}

#define SLAMVDB_AVX2 __attribute__((target("avx2")))

// The low 32 bits of each 64-bit lane: a comparison mask of doubles as one of ints.
SLAMVDB_AVX2 inline __m128i lane_mask32(__m256d mask) {
  const __m256i lo = _mm256_permutevar8x32_epi32(_mm256_castpd_si256(mask), _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6));
  return _mm256_castsi256_si128(lo);
}

// Four points at a time; a group with anything rare in it goes through prepare_one.
SLAMVDB_AVX2 void prepare_rays_avx2(const RaySetup& s, std::span<const Vec3f> points, Vec3d* to, uint32_t* sort_keys,
                                    uint64_t* hit_words, PreparedRays& out) {
  const Eigen::Matrix3d& R = s.R;
  const __m256d min2 = _mm256_set1_pd(s.min_range * s.min_range), max2 = _mm256_set1_pd(s.max_range * s.max_range),
                clear2 = _mm256_set1_pd(s.clear_range * s.clear_range), max_range = _mm256_set1_pd(s.max_range),
                clear_range = _mm256_set1_pd(s.clear_range), largest = _mm256_set1_pd(std::numeric_limits<double>::max()),
                zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0), inv = _mm256_set1_pd(s.inv_voxel_size),
                extent = _mm256_set1_pd(kMaxGridCoordinate), sign = _mm256_set1_pd(-0.0);
  __m256d r[9], o[3];
  for (int i = 0; i < 9; ++i) r[i] = _mm256_set1_pd(R(i / 3, i % 3));
  for (int a = 0; a < 3; ++a) o[a] = _mm256_set1_pd(s.origin[a]);
  const RayCube& cube = s.cube;
  __m128i from[3], cube_lo[3], lo[3], hi[3], shift_hi[3];
  for (int a = 0; a < 3; ++a) {
    from[a] = _mm_set1_epi32(s.from_key[a]);
    cube_lo[a] = _mm_set1_epi32(cube.lo[a]);
    lo[a] = _mm_set1_epi32(out.lo[a]), hi[a] = _mm_set1_epi32(out.hi[a]);
    shift_hi[a] = _mm_cvtsi32_si128(9 + a * cube.side_bits);
  }
  const __m128i side = _mm_set1_epi32(cube.side_voxels()), seven = _mm_set1_epi32(7), no_hit = _mm_set1_epi32(static_cast<int>(no_hit_bit(cube))),
                max_steps = _mm_set1_epi32(1023), tiles = _mm_set1_epi32(kRayTiles), last_tile = _mm_set1_epi32(kRayTiles - 1);
  const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff)), half_tiles = _mm_set1_ps(kRayTiles / 2),
               one_f = _mm_set1_ps(1.0f), zero_f = _mm_setzero_ps();
  std::size_t beyond = 0, i = 0;
  for (; i + 4 <= points.size(); i += 4) {
    const float* f = points[i].data();  // Vec3f: three packed floats
    const __m256d x = _mm256_cvtps_pd(_mm_setr_ps(f[0], f[3], f[6], f[9])),
                  y = _mm256_cvtps_pd(_mm_setr_ps(f[1], f[4], f[7], f[10])),
                  z = _mm256_cvtps_pd(_mm_setr_ps(f[2], f[5], f[8], f[11]));
    const __m256d range2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(x, x), _mm256_mul_pd(y, y)), _mm256_mul_pd(z, z));
    const __m256d ok = _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(range2, zero, _CMP_GT_OQ), _mm256_cmp_pd(range2, min2, _CMP_GE_OQ)),
                                     _mm256_cmp_pd(range2, largest, _CMP_LE_OQ));
    auto one_by_one = [&] {
      for (std::size_t l = i; l < i + 4; ++l) prepare_one(s, points[l], to[l], sort_keys[l], hit_words, out);
    };
    if (_mm256_movemask_pd(ok) != 0xf) {
      one_by_one();
      continue;
    }
    const __m256d hit = _mm256_cmp_pd(range2, max2, _CMP_LE_OQ);
    const __m256d whole = _mm256_and_pd(hit, _mm256_cmp_pd(range2, clear2, _CMP_LE_OQ));  // not cut short
    __m256d rp[3];
    for (int a = 0; a < 3; ++a)
      rp[a] = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(r[3 * a], x), _mm256_mul_pd(r[3 * a + 1], y)), _mm256_mul_pd(r[3 * a + 2], z));
    __m256d end_scale = one, to_scale = one;
    if (_mm256_movemask_pd(whole) != 0xf) {
      const __m256d range = _mm256_sqrt_pd(range2), length = _mm256_blendv_pd(max_range, range, hit);
      end_scale = _mm256_blendv_pd(_mm256_div_pd(length, range), one, whole);
      to_scale = _mm256_blendv_pd(_mm256_div_pd(_mm256_min_pd(length, clear_range), range), one, whole);
    }
    __m256d end[3], seg[3], inside = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    for (int a = 0; a < 3; ++a) {
      end[a] = _mm256_mul_pd(_mm256_add_pd(o[a], _mm256_mul_pd(rp[a], end_scale)), inv);
      seg[a] = _mm256_mul_pd(_mm256_add_pd(o[a], _mm256_mul_pd(rp[a], to_scale)), inv);
      inside = _mm256_and_pd(inside, _mm256_cmp_pd(_mm256_andnot_pd(sign, end[a]), extent, _CMP_LT_OQ));
      inside = _mm256_and_pd(inside, _mm256_cmp_pd(_mm256_andnot_pd(sign, seg[a]), extent, _CMP_LT_OQ));
    }
    if (_mm256_movemask_pd(inside) != 0xf) {
      one_by_one();
      continue;
    }
    const __m128i hit_i = lane_mask32(hit), hit_cut = lane_mask32(_mm256_andnot_pd(whole, hit));
    __m128i to_key[3], k[3], steps = _mm_setzero_si128(), contained = _mm_set1_epi32(-1), bit = _mm_setzero_si128();
    for (int a = 0; a < 3; ++a) {
      to_key[a] = _mm256_cvttpd_epi32(_mm256_floor_pd(seg[a]));
      k[a] = _mm_blendv_epi8(to_key[a], _mm256_cvttpd_epi32(_mm256_floor_pd(end[a])), hit_cut);
      steps = _mm_add_epi32(steps, _mm_abs_epi32(_mm_sub_epi32(to_key[a], from[a])));
      lo[a] = _mm_min_epi32(lo[a], _mm_min_epi32(to_key[a], k[a]));
      hi[a] = _mm_max_epi32(hi[a], _mm_max_epi32(to_key[a], k[a]));
      const __m128i c = _mm_sub_epi32(k[a], cube_lo[a]);
      contained = _mm_and_si128(contained, _mm_andnot_si128(_mm_cmplt_epi32(c, _mm_setzero_si128()), _mm_cmplt_epi32(c, side)));
      bit = _mm_or_si128(bit, _mm_or_si128(_mm_slli_epi32(_mm_and_si128(c, seven), 3 * a),
                                           _mm_sll_epi32(_mm_srli_epi32(c, 3), shift_hi[a])));
    }
    if (_mm_movemask_ps(_mm_castsi128_ps(_mm_andnot_si128(contained, hit_i))) != 0) {
      one_by_one();  // (the box took this group's keys already: a larger box is only slower)
      continue;
    }
    // ray_tile_of, in float.
    const __m128 d[3] = {_mm256_cvtpd_ps(rp[0]), _mm256_cvtpd_ps(rp[1]), _mm256_cvtpd_ps(rp[2])};
    const __m128 ax = _mm_and_ps(d[0], abs_mask), ay = _mm_and_ps(d[1], abs_mask), az = _mm_and_ps(d[2], abs_mask);
    const __m128 face_x = _mm_and_ps(_mm_cmpge_ps(ax, ay), _mm_cmpge_ps(ax, az)),
                 face_y = _mm_andnot_ps(face_x, _mm_cmpge_ps(ay, az));
    const __m128 m = _mm_div_ps(one_f, _mm_max_ps(ax, _mm_max_ps(ay, az)));
    auto by_face = [&](__m128 if_x, __m128 if_y, __m128 if_z) SLAMVDB_AVX2 {
      return _mm_blendv_ps(_mm_blendv_ps(if_z, if_y, face_y), if_x, face_x);
    };
    auto tile_coordinate = [&](__m128 v) SLAMVDB_AVX2 {
      return _mm_min_epi32(_mm_cvttps_epi32(_mm_mul_ps(_mm_add_ps(_mm_mul_ps(v, m), one_f), half_tiles)), last_tile);
    };
    const __m128i iu = tile_coordinate(by_face(d[1], d[2], d[0])), iv = tile_coordinate(by_face(d[2], d[0], d[1]));
    const __m128i face = _mm_castps_si128(by_face(_mm_castsi128_ps(_mm_set1_epi32(0)), _mm_castsi128_ps(_mm_set1_epi32(1)),
                                                  _mm_castsi128_ps(_mm_set1_epi32(2))));
    const __m128i negative = _mm_srli_epi32(_mm_castps_si128(_mm_cmplt_ps(by_face(d[0], d[1], d[2]), zero_f)), 31);
    const __m128i tile = _mm_add_epi32(
        _mm_mullo_epi32(_mm_add_epi32(_mm_mullo_epi32(_mm_add_epi32(_mm_add_epi32(face, face), negative), tiles), iu), tiles), iv);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sort_keys + i), _mm_or_si128(_mm_slli_epi32(tile, 10), _mm_min_epi32(steps, max_steps)));
    alignas(32) double tx[4], ty[4], tz[4];
    _mm256_store_pd(tx, seg[0]), _mm256_store_pd(ty, seg[1]), _mm256_store_pd(tz, seg[2]);
    alignas(16) uint32_t bits[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(bits), _mm_blendv_epi8(no_hit, bit, hit_i));
    for (int l = 0; l < 4; ++l) {
      to[i + l] = Vec3d(tx[l], ty[l], tz[l]);
      set_bit(hit_words, bits[l]);
    }
    beyond += 4 - std::popcount(static_cast<unsigned>(_mm256_movemask_pd(hit)));
  }
  out.beyond_max_range += beyond;
  alignas(16) int32_t lanes[4];
  for (int a = 0; a < 3; ++a) {
    _mm_store_si128(reinterpret_cast<__m128i*>(lanes), lo[a]);
    out.lo[a] = std::min({out.lo[a], lanes[0], lanes[1], lanes[2], lanes[3]});
    _mm_store_si128(reinterpret_cast<__m128i*>(lanes), hi[a]);
    out.hi[a] = std::max({out.hi[a], lanes[0], lanes[1], lanes[2], lanes[3]});
  }
  for (; i < points.size(); ++i) prepare_one(s, points[i], to[i], sort_keys[i], hit_words, out);
}

}  // namespace

void prepare_rays_scalar(const RaySetup& setup, std::span<const Vec3f> points, Vec3d* to, uint32_t* sort_keys,
                         uint64_t* hit_words, PreparedRays& out) {
  for (std::size_t i = 0; i < points.size(); ++i) prepare_one(setup, points[i], to[i], sort_keys[i], hit_words, out);
}

void prepare_rays(const RaySetup& setup, std::span<const Vec3f> points, Vec3d* to, uint32_t* sort_keys,
                  uint64_t* hit_words, PreparedRays& out) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2 && setup.cube.side_bits != 0) prepare_rays_avx2(setup, points, to, sort_keys, hit_words, out);
  else prepare_rays_scalar(setup, points, to, sort_keys, hit_words, out);
}

}  // namespace slamvdb
