#include "slamvdb/map/occupancy_rays.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace slamvdb {
namespace {

// A sensor at a non-grid-aligned pose, 0.25 m voxels, 25 m clearing and 40 m hits: hits between
// 25 m and the cube's edge are marked, hits beyond it are handed back.
RaySetup make_ray_setup() {
  RaySetup s;
  s.R = Eigen::AngleAxisd(0.7, Vec3d(0.2, -0.3, 1.0).normalized()).toRotationMatrix();
  s.origin = Vec3d(103.37, -20.61, 1.12);
  s.inv_voxel_size = 4.0;
  s.min_range = 0.5, s.max_range = 40.0, s.clear_range = 25.0;
  s.from_key = key_of_point<VoxelKey>(s.origin, s.inv_voxel_size);
  s.cube = RayCube::around(s.from_key, static_cast<int>(std::ceil(s.clear_range * s.inv_voxel_size)) + 1);
  return s;
}

// Points of every kind, mostly ordinary ones, the rare ones scattered so that they fall into
// groups of four with ordinary ones.
std::vector<Vec3f> points_of_every_kind(std::mt19937& rng, int n) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), r(0.0f, 60.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  std::vector<Vec3f> points;
  for (int i = 0; i < n; ++i) {
    Vec3f d(u(rng), u(rng), 0.3f * u(rng));
    if (i % 11 == 0) d.y() = 0;  // a zero coordinate
    Vec3f p = d.normalized() * r(rng);
    switch (i % 97) {
      case 5: p.x() = nan; break;
      case 17: p.z() = inf; break;
      case 23: p = Vec3f::Zero(); break;                 // no return
      case 41: p = d.normalized() * 0.3f; break;         // too close
      case 59: p = d.normalized() * 1.0e9f; break;       // beyond max range, far out of the grid
      case 71: p = Vec3f(0.0f, 0.0f, 25.0f); break;      // exactly at the clearing range
      default: break;
    }
    points.push_back(p);
  }
  return points;
}

struct PreparedPoints {
  std::vector<Vec3d> to;
  std::vector<uint32_t> keys;
  std::vector<uint64_t> hit_words;
  PreparedRays rays;
};

template <class Prepare>
PreparedPoints prepare_points(const RaySetup& s, const std::vector<Vec3f>& points, Prepare prepare) {
  PreparedPoints p{std::vector<Vec3d>(points.size(), Vec3d::Zero()), std::vector<uint32_t>(points.size(), 0),
             std::vector<uint64_t>(s.cube.num_words(), 0), PreparedRays(s.from_key)};
  prepare(s, std::span<const Vec3f>(points), p.to.data(), p.keys.data(), p.hit_words.data(), p.rays);
  return p;
}

TEST(PrepareRays, Avx2AndScalarAgreeBitForBit) {
  std::mt19937 rng(5);
  const RaySetup s = make_ray_setup();
  for (int n : {0, 3, 4, 9, 20000}) {
    const std::vector<Vec3f> points = points_of_every_kind(rng, n);
    const PreparedPoints a = prepare_points(s, points, prepare_rays), b = prepare_points(s, points, prepare_rays_scalar);
    EXPECT_EQ(a.keys, b.keys) << n;
    for (int i = 0; i < n; ++i) {
      if (b.keys[i] != kNotCast) {
        ASSERT_EQ(a.to[i], b.to[i]) << i;  // the same doubles
      }
    }
    EXPECT_EQ(a.hit_words, b.hit_words) << n;
    EXPECT_EQ(a.rays.nonfinite, b.rays.nonfinite);
    EXPECT_EQ(a.rays.no_return, b.rays.no_return);
    EXPECT_EQ(a.rays.too_close, b.rays.too_close);
    EXPECT_EQ(a.rays.out_of_extent, b.rays.out_of_extent);
    EXPECT_EQ(a.rays.beyond_max_range, b.rays.beyond_max_range);
    EXPECT_EQ(a.rays.hits_outside, b.rays.hits_outside);
    EXPECT_EQ(a.rays.lo, b.rays.lo);
    EXPECT_EQ(a.rays.hi, b.rays.hi);
  }
}

// What each kind of point becomes, by the definitions (not by comparing the two paths).
TEST(PrepareRays, EachKindOfPoint) {
  std::mt19937 rng(8);
  const RaySetup s = make_ray_setup();
  const std::vector<Vec3f> points = points_of_every_kind(rng, 20000);
  const PreparedPoints p = prepare_points(s, points, prepare_rays);
  std::size_t nonfinite = 0, no_return = 0, too_close = 0, beyond = 0, outside = 0, out_of_extent = 0;
  std::vector<uint64_t> expected_hits(s.cube.num_words(), 0);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3d q = points[i].cast<double>();
    const double range = q.norm();
    if (!q.allFinite()) {
      ++nonfinite;
      EXPECT_EQ(p.keys[i], kNotCast);
      continue;
    }
    if (range == 0.0 || range < s.min_range) {
      ++(range == 0.0 ? no_return : too_close);
      EXPECT_EQ(p.keys[i], kNotCast);
      continue;
    }
    const Vec3d dir = s.R * q / range;
    const Vec3d end = (s.origin + dir * std::min(range, s.max_range)) * s.inv_voxel_size;
    if (!in_grid_extent(end)) {
      ++out_of_extent;
      EXPECT_EQ(p.keys[i], kNotCast);
      continue;
    }
    ASSERT_NE(p.keys[i], kNotCast) << i;
    // The segment ends at the hit or at the clearing range, whichever is nearer.
    const Vec3d to = (s.origin + dir * std::min({range, s.max_range, s.clear_range})) * s.inv_voxel_size;
    EXPECT_LT((p.to[i] - to).norm(), 1e-9) << i;
    const VoxelKey to_key = key_of_point<VoxelKey>(p.to[i], 1.0);
    EXPECT_EQ(p.keys[i] & 1023u, std::min(1023u, static_cast<uint32_t>((to_key - s.from_key).cwiseAbs().sum())));
    EXPECT_EQ(p.keys[i] >> 10, ray_tile_of(Vec3f((s.R * q).cast<float>())));
    if (range > s.max_range) {
      ++beyond;
      continue;
    }
    const VoxelKey k = key_of_point<VoxelKey>((s.origin + s.R * q) * s.inv_voxel_size, 1.0);
    if (!s.cube.contains(k)) {
      ++outside;
      continue;
    }
    const uint32_t bit = s.cube.bit_of(k);
    expected_hits[bit >> 6] |= uint64_t{1} << (bit & 63);
  }
  EXPECT_EQ(p.rays.nonfinite, nonfinite);
  EXPECT_EQ(p.rays.no_return, no_return);
  EXPECT_EQ(p.rays.too_close, too_close);
  EXPECT_EQ(p.rays.out_of_extent, out_of_extent);
  EXPECT_EQ(p.rays.beyond_max_range, beyond);
  EXPECT_EQ(p.rays.hits_outside.size(), outside);
  EXPECT_GT(nonfinite, 0u);
  EXPECT_GT(beyond, 1000u);
  EXPECT_GT(outside, 100u);
  // Rays without a hit mark the spare brick; the cube's bits are exactly the hits.
  std::vector<uint64_t> marked = p.hit_words;
  EXPECT_NE(marked[marked.size() - 8], 0u);
  std::fill(marked.end() - 8, marked.end(), 0);
  EXPECT_EQ(marked, expected_hits);
}

}  // namespace
}  // namespace slamvdb
