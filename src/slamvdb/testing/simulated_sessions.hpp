#pragma once
// For tests only: maps of two sessions (drives) over one SIMULATED terrain, made directly from
// the terrain's surface samples, for the alignment tests (sessions/, `slamvdb align`): a
// procedural terrain (undulating ground, boxes, trees, poles) along a winding route, cut into
// submaps of 50 m of route, each holding the occupied 0.25 m voxels within 35 m of its stretch,
// anchored (world axes, voxel corner) where its stretch starts, as the mapper anchors submaps.
// A session sees the world through T_session_world (its own world frame), re-voxelised in it.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/sessions/place_descriptors.hpp"

namespace slamvdb::testing {

using sessions::SessionSubmap;

struct AlignTestWorld {
  std::vector<Vec3d> points;  // surface samples, world frame
  std::vector<Vec3d> route;   // one sample per metre
};

class AlignTestRng {
 public:
  explicit AlignTestRng(uint64_t seed) : state_(seed * 0x9E3779B97F4A7C15ULL + 1) {}
  double uniform(double lo, double hi) {  // splitmix64
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    return lo + (hi - lo) * static_cast<double>(z >> 11) * 0x1.0p-53;
  }

 private:
  uint64_t state_;
};

inline constexpr double kAlignTestRange = 35.0;
inline constexpr double kAlignTestVoxel = 0.25;

// `repeat` > 0: look-alike places, a straight route whose ground and objects repeat every
// `repeat` metres along it.
inline AlignTestWorld make_align_world(uint64_t seed, double length, double repeat = 0.0) {
  AlignTestRng rng(seed);
  const double phase = rng.uniform(0, 6.28), g1 = rng.uniform(0, 6.28), g2 = rng.uniform(0, 6.28);
  const double bend = repeat > 0 ? 0.0 : 15.0, swell = repeat > 0 ? 0.0 : 0.3;
  const auto route_y = [&](double x) { return bend * std::sin(x / 50.0 + phase); };
  const auto ground = [&](double x, double y) { return swell * std::sin(x / 17.0 + g1) + 0.3 * std::cos(y / 13.0 + g2); };
  AlignTestWorld w;
  for (double x = 0; x <= length; x += 1.0) w.route.emplace_back(x, route_y(x), ground(x, route_y(x)));
  // Ground samples jittered off any lattice: samples on the voxel grid's boundaries would all
  // land on one side and shift the map by half a voxel.
  for (double gx = -kAlignTestRange; gx <= length + kAlignTestRange; gx += kAlignTestVoxel)
    for (double gy = route_y(gx) - kAlignTestRange; gy <= route_y(gx) + kAlignTestRange; gy += kAlignTestVoxel) {
      const double x = gx + rng.uniform(-0.5, 0.5) * kAlignTestVoxel, y = gy + rng.uniform(-0.5, 0.5) * kAlignTestVoxel;
      w.points.emplace_back(x, y, ground(x, y));
    }
  const double span = repeat > 0 ? repeat : length + 2 * kAlignTestRange;
  const int objects = static_cast<int>(span * 2 * kAlignTestRange / 120.0);
  std::vector<Vec3d> object_points;
  for (int i = 0; i < objects; ++i) {
    const double x = repeat > 0 ? rng.uniform(0, repeat) : rng.uniform(-kAlignTestRange, length + kAlignTestRange);
    const double side = rng.uniform(0, 1) < 0.5 ? -1.0 : 1.0;
    const double y = route_y(x) + side * rng.uniform(4.0, kAlignTestRange);
    const double z0 = ground(x, y);
    const double kind = rng.uniform(0, 1);
    if (kind < 0.4) {  // a box: its sides and top
      const double a = rng.uniform(1, 4), b = rng.uniform(1, 4), h = rng.uniform(1, 3), yaw = rng.uniform(0, 3.14);
      const Eigen::Matrix2d R = Eigen::Rotation2Dd(yaw).toRotationMatrix();
      for (double u = -a / 2; u <= a / 2; u += 0.2)
        for (double v = -b / 2; v <= b / 2; v += 0.2)
          for (double z = 0; z <= h; z += 0.2) {
            const bool surface = std::abs(u) > a / 2 - 0.2 || std::abs(v) > b / 2 - 0.2 || z > h - 0.2;
            if (!surface) continue;
            const Eigen::Vector2d p = Eigen::Vector2d(x, y) + R * Eigen::Vector2d(u, v);
            object_points.emplace_back(p.x(), p.y(), z0 + z);
          }
    } else {  // a tree (trunk and crown) or a pole
      const bool tree = kind < 0.8;
      const double r = tree ? rng.uniform(0.2, 0.4) : 0.15, h = tree ? rng.uniform(2, 4) : rng.uniform(5, 8);
      for (double z = 0; z <= h; z += 0.2)
        for (double t = 0; t < 6.28; t += 0.2 / r) object_points.emplace_back(x + r * std::cos(t), y + r * std::sin(t), z0 + z);
      if (tree) {
        const double c = rng.uniform(1.5, 3.0);
        for (double el = -1.5; el <= 1.5; el += 0.2 / c)
          for (double t = 0; t < 6.28; t += 0.2 / (c * std::max(0.1, std::cos(el))))
            object_points.emplace_back(x + c * std::cos(el) * std::cos(t), y + c * std::cos(el) * std::sin(t),
                                  z0 + h + c + c * std::sin(el));
      }
    }
  }
  if (repeat <= 0) {
    w.points.insert(w.points.end(), object_points.begin(), object_points.end());
    return w;
  }
  for (double shift = -std::ceil(kAlignTestRange / repeat) * repeat; shift <= length + kAlignTestRange; shift += repeat)
    for (const Vec3d& p : object_points) w.points.emplace_back(p.x() + shift, p.y(), p.z());
  return w;
}

// A session that drove the route from metre `begin` to `end`, in a world frame where the
// simulated world's points are at T_session_world * p.
inline std::vector<SessionSubmap> make_align_session(const AlignTestWorld& w, const Pose& T_session_world, int begin, int end,
                                              int submap_length = 50) {
  std::vector<SessionSubmap> submaps;
  for (int s = begin; s < end; s += submap_length) {
    const int stop = std::min(end, s + submap_length);
    SessionSubmap submap;
    submap.id = static_cast<int>(submaps.size());
    const Vec3d start = T_session_world * w.route[s];
    submap.T_world_submap.translation() = (start / kAlignTestVoxel).array().floor().matrix() * kAlignTestVoxel;
    std::set<std::tuple<int, int, int>> voxels;
    for (const Vec3d& p : w.points) {
      if (p.x() < w.route[s].x() - kAlignTestRange || p.x() > w.route[stop].x() + kAlignTestRange) continue;
      bool seen = false;
      for (int k = s; k <= stop && !seen; k += 2) seen = (p - w.route[k]).head<2>().norm() < kAlignTestRange;
      if (!seen) continue;
      const Vec3d q = (T_session_world * p - submap.T_world_submap.translation()) / kAlignTestVoxel;
      voxels.insert({static_cast<int>(std::floor(q.x())), static_cast<int>(std::floor(q.y())),
                     static_cast<int>(std::floor(q.z()))});
    }
    for (const auto& [i, j, k] : voxels)
      submap.occupied_submap.emplace_back((i + 0.5) * kAlignTestVoxel, (j + 0.5) * kAlignTestVoxel, (k + 0.5) * kAlignTestVoxel);
    submaps.push_back(std::move(submap));
  }
  return submaps;
}

inline Pose make_align_test_pose(double yaw_deg, const Vec3d& t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = t;
  return T;
}

// A map (SIMULATED) holding the session's submaps as finished submaps: each occupied voxel centre
// set occupied (log-odds at the clamp), no semantics. Voxel size kAlignTestVoxel.
inline SemanticMap make_align_session_map(const std::vector<SessionSubmap>& submaps, const std::string& source) {
  MapParams params;
  params.occupancy.voxel_size = kAlignTestVoxel;
  MapInfo info;
  info.source = source;
  SemanticMap map(params, info);
  for (const SessionSubmap& s : submaps) {
    VoxelMap voxels(params);
    for (const Vec3f& p : s.occupied_submap)
      voxels.occupancy().set_log_odds(voxels.occupancy().key_of(p.cast<double>()), params.occupancy.clamp_max);
    SubmapInfo submap;
    submap.id = s.id;
    submap.T_world_submap = s.T_world_submap;
    submap.finished = true;
    map.add_finished_submap(submap, std::move(voxels));
  }
  return map;
}

}  // namespace slamvdb::testing
