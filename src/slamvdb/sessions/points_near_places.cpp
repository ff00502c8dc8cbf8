#include "slamvdb/sessions/points_near_places.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <utility>

#include "slamvdb/core/error.hpp"

namespace slamvdb::sessions {

SubmapClouds::SubmapClouds(std::vector<std::vector<Vec3d>> clouds) : clouds_(std::move(clouds)) {
  bounds_.resize(clouds_.size());
  for (std::size_t i = 0; i < clouds_.size(); ++i)
    for (const Vec3d& p : clouds_[i]) bounds_[i].extend(p);
}

namespace {

// The horizontal box (world frame) holding a submap-frame box moved by T: the box of its corners.
Eigen::AlignedBox2d world_footprint(const Eigen::AlignedBox3d& box_submap, const Pose& T_world_submap) {
  Eigen::AlignedBox2d out;
  for (int c = 0; c < 8; ++c) {
    const Eigen::AlignedBox3d::CornerType corner = static_cast<Eigen::AlignedBox3d::CornerType>(c);
    out.extend((T_world_submap * box_submap.corner(corner)).head<2>());
  }
  return out;
}

}  // namespace

std::vector<Vec3d> SubmapClouds::world_points_near(const std::vector<Pose>& T_world_submaps,
                                                   const std::vector<Eigen::Vector2d>& centres, double radius,
                                                   std::optional<std::size_t> only_submap) const {
  if (T_world_submaps.size() != clouds_.size()) throw Error("world_points_near: one pose per submap is needed");
  const double r2 = radius * radius;
  // A centre farther than this from a submap's footprint reaches none of its points. The margin
  // (1 mm) covers the rounding of the moved corners, so that no point the exact test keeps is lost.
  const double reach2 = (radius + 1e-3) * (radius + 1e-3);
  std::vector<std::vector<Vec3d>> kept(clouds_.size());
  tbb::parallel_for(std::size_t{0}, clouds_.size(), [&](std::size_t i) {
    if ((only_submap && *only_submap != i) || bounds_[i].isEmpty()) return;
    const Pose& T_world_submap = T_world_submaps[i];
    const Eigen::AlignedBox2d footprint = world_footprint(bounds_[i], T_world_submap);
    std::vector<Eigen::Vector2d> near;
    for (const Eigen::Vector2d& c : centres)
      if (footprint.squaredExteriorDistance(c) <= reach2) near.push_back(c);
    if (near.empty()) return;
    for (const Vec3d& x_submap : clouds_[i]) {
      const Vec3d x = T_world_submap * x_submap;
      if (std::any_of(near.begin(), near.end(),
                      [&](const Eigen::Vector2d& c) { return (x.head<2>() - c).squaredNorm() <= r2; }))
        kept[i].push_back(x);
    }
  });
  std::size_t total = 0;
  for (const std::vector<Vec3d>& k : kept) total += k.size();
  std::vector<Vec3d> out;
  out.reserve(total);
  for (const std::vector<Vec3d>& k : kept) out.insert(out.end(), k.begin(), k.end());
  return out;
}

}  // namespace slamvdb::sessions
