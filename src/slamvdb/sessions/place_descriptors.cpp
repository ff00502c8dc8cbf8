#include "slamvdb/sessions/place_descriptors.hpp"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/localization/preprocessing.hpp"

namespace slamvdb::sessions {

void PlaceConfig::validate() const {
  const auto require = [](bool ok, const std::string& what) {
    if (!ok) throw Error("invalid place setting: " + what);
  };
  require(cloud_voxel > 0.0, fmt::format("cloud voxel {} m must be > 0", cloud_voxel));
  require(seed_spacing > 0.0 && shift_radius > 0.0, "seed spacing and shift radius must be > 0");
  require(merge_distance >= 0.0, "merge distance must be >= 0");
  require(max_places_per_submap > 0, "max places per submap must be > 0");
  require(ground_quantile >= 0.0 && ground_quantile <= 1.0, "ground quantile must be in [0, 1]");
  scan_context.validate();
}

std::vector<Vec3d> thinned_cloud(const SessionSubmap& submap, const PlaceConfig& config) {
  std::vector<Vec3d> points;
  points.reserve(submap.occupied_submap.size());
  for (const Vec3f& p : submap.occupied_submap)
    if (p.allFinite()) points.push_back(p.cast<double>());
  return localization::voxel_downsample(points, config.cloud_voxel);
}

std::vector<Vec3d> points_around(const std::vector<Vec3d>& cloud, const Place& place, double radius) {
  std::vector<Vec3d> out;
  const double r2 = radius * radius;
  for (const Vec3d& p : cloud) {
    const Vec3d d = p - place.centre_submap;
    if (d.head<2>().squaredNorm() <= r2) out.push_back(d);
  }
  return out;
}

namespace {

// Mean shift with a flat kernel on the horizontal positions, from `start`, a few steps.
Eigen::Vector2d place_mode(const std::vector<Vec3d>& cloud, Eigen::Vector2d start, double radius) {
  const double r2 = radius * radius;
  for (int step = 0; step < 30; ++step) {
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    std::size_t n = 0;
    for (const Vec3d& p : cloud)
      if ((p.head<2>() - start).squaredNorm() <= r2) sum += p.head<2>(), ++n;
    if (n == 0) break;
    const Eigen::Vector2d next = sum / static_cast<double>(n);
    const double moved = (next - start).norm();
    start = next;
    if (moved < 0.01) break;
  }
  return start;
}

std::vector<Place> submap_places(std::size_t index, const std::vector<Vec3d>& cloud, const PlaceConfig& config) {
  // Seeds: the densest columns of the coarse grid, densest first (ties by cell, for determinism).
  std::map<std::pair<long, long>, std::size_t> columns;
  for (const Vec3d& p : cloud)
    ++columns[{std::lround(std::floor(p.x() / config.seed_spacing)), std::lround(std::floor(p.y() / config.seed_spacing))}];
  std::vector<std::pair<std::size_t, std::pair<long, long>>> seeds;
  for (const auto& [cell, n] : columns) seeds.push_back({n, cell});
  std::stable_sort(seeds.begin(), seeds.end(), [](const auto& a, const auto& b) { return a.first > b.first; });

  std::vector<Place> places;
  const double radius = config.scan_context.max_radius;
  for (const auto& seed : seeds) {
    if (places.size() >= config.max_places_per_submap) break;
    const Eigen::Vector2d start((seed.second.first + 0.5) * config.seed_spacing,
                                (seed.second.second + 0.5) * config.seed_spacing);
    const Eigen::Vector2d mode = place_mode(cloud, start, config.shift_radius);
    const bool near_another = std::any_of(places.begin(), places.end(), [&](const Place& q) {
      return (q.centre_submap.head<2>() - mode).norm() < config.merge_distance;
    });
    if (near_another) continue;
    Place place;
    place.submap = index;
    place.centre_submap << mode.x(), mode.y(), 0.0;
    std::vector<Vec3d> around = points_around(cloud, place, radius);
    if (around.size() < config.min_place_voxels) continue;
    // Ground level: a low quantile of the heights, so descriptors of two sessions whose anchors
    // sit at different heights compare.
    std::vector<double> heights(around.size());
    std::transform(around.begin(), around.end(), heights.begin(), [](const Vec3d& p) { return p.z(); });
    const auto q = heights.begin() + static_cast<std::ptrdiff_t>(config.ground_quantile * (heights.size() - 1));
    std::nth_element(heights.begin(), q, heights.end());
    place.centre_submap.z() = *q;
    for (Vec3d& p : around) p.z() -= *q;
    place.voxels = around.size();
    place.descriptor = localization::make_scan_context(around, config.scan_context);
    places.push_back(std::move(place));
  }
  return places;
}

}  // namespace

std::vector<Place> make_places(const std::vector<std::vector<Vec3d>>& thinned_clouds, const PlaceConfig& config) {
  config.validate();
  // Each submap's places alone (in parallel), then in submap order.
  std::vector<std::vector<Place>> found(thinned_clouds.size());
  tbb::parallel_for(std::size_t{0}, thinned_clouds.size(),
                    [&](std::size_t i) { found[i] = submap_places(i, thinned_clouds[i], config); });
  std::vector<Place> places;
  for (std::vector<Place>& f : found)
    places.insert(places.end(), std::make_move_iterator(f.begin()), std::make_move_iterator(f.end()));
  return places;
}

std::vector<Place> make_places(const std::vector<SessionSubmap>& submaps, const PlaceConfig& config) {
  config.validate();
  std::vector<std::vector<Vec3d>> clouds;
  clouds.reserve(submaps.size());
  for (const SessionSubmap& submap : submaps) clouds.push_back(thinned_cloud(submap, config));
  return make_places(clouds, config);
}

}  // namespace slamvdb::sessions
