#include "slamvdb/sessions/session_refinement.hpp"

#include <algorithm>
#include <cstdint>
#include <span>

#include "slamvdb/localization/preprocessing.hpp"
#include "slamvdb/localization/registration.hpp"

namespace slamvdb::sessions {

namespace {

// Every submap's voxels (thinned to `voxel`) within `radius` (horizontally) of any of the places,
// in the world frame of the session. All submaps, not only the places' own: a place's
// surroundings cut at its submap's edge would pull the other session's points inwards. With
// `only_submap` (an index), that submap's voxels alone.
std::vector<Vec3d> session_cloud_near(const AlignmentSession& session, const std::set<std::size_t>& places,
                                      double radius, double voxel, std::optional<std::size_t> only_submap = {}) {
  std::vector<Eigen::Vector2d> centres;
  for (const std::size_t p : places) centres.push_back(session.T_world_place(p).translation().head<2>());
  return localization::voxel_downsample(
      session.dense_clouds.world_points_near(session.T_world_submaps, centres, radius, only_submap), voxel);
}

// Every `keep_one_in`-th point on average, chosen by a hash of its index: a subset with no
// geometric pattern. Thinning by keeping the first point of each coarser voxel picks, from
// voxels stored in key order, the same corner of every coarse cell, and that biased the
// refinement by 0.035 m along the drive (on sloped ground the kept voxels sit on one side).
std::vector<Vec3d> unbiased_subset(const std::vector<Vec3d>& points, uint64_t keep_one_in) {
  std::vector<Vec3d> out;
  out.reserve(points.size() / keep_one_in + 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    uint64_t z = (static_cast<uint64_t>(i) + 1) * 0x9E3779B97F4A7C15ULL;  // splitmix64's finaliser
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    if ((z ^ (z >> 31)) % keep_one_in == 0) out.push_back(points[i]);
  }
  return out;
}

SurfaceRefinementConfig surface_config(const AlignmentConfig& config) {
  SurfaceRefinementConfig surface;
  surface.voxel = config.refine_voxel;
  surface.normal_radius = 2.4 * config.refine_voxel;
  surface.max_distance = config.refine_voxel;
  return surface;
}

}  // namespace

RefinementSource refinement_source(const AlignmentSession& other, const std::set<std::size_t>& other_places,
                                   const AlignmentConfig& config, std::optional<std::size_t> only_submap) {
  RefinementSource s;
  s.points = session_cloud_near(other, other_places, config.places.scan_context.max_radius, config.refine_voxel,
                                only_submap);
  // The ICP source at twice the cloud voxel: the dense target gives each of its points a near
  // neighbour, and every point costs 27 hash look-ups per iteration (the refinement was half
  // the alignment's time with the source at the cloud voxel, for no gain in accuracy).
  // At most refine_points of them (an unbiased subset): a rigid transform over a whole map is
  // fixed long before every metre of a 3 km drive is used, and the cost grows with the points.
  std::vector<Vec3d> downsampled = localization::voxel_downsample(s.points, 2.0 * config.places.cloud_voxel);
  s.icp = downsampled.size() > config.refine_points
              ? unbiased_subset(downsampled, (downsampled.size() + config.refine_points - 1) / config.refine_points)
              : std::move(downsampled);
  // The surface step: a quarter of the voxels (each a voxel centre as stored) or fewer.
  s.surface = unbiased_subset(
      s.points, std::max<uint64_t>(4, (s.points.size() + config.refine_points - 1) / config.refine_points));
  return s;
}

RefinementBase::RefinementBase(const AlignmentSession& base, const std::set<std::size_t>& base_places,
                               const AlignmentConfig& config)
    : config_(&config),
      points_(session_cloud_near(base, base_places, config.places.scan_context.max_radius + 10.0,
                                 config.refine_voxel)),
      target_(config.refine_voxel, 1e9, 20) {
  target_.add_points(points_);
}

void RefinementBase::add_planes_near(const RefinementSource& source, const Pose& T_base_other) {
  std::vector<Vec3d> near;
  near.reserve(source.points.size());
  for (const Vec3d& p : source.points) near.push_back(T_base_other * p);
  planes_ = std::make_shared<const SurfacePlanes>(points_, near, surface_config(*config_), 2.0 * config_->places.cloud_voxel);
}

Pose RefinementBase::icp(const RefinementSource& source, const Pose& start, bool from_refined) const {
  const double cloud_voxel = config_->places.cloud_voxel;
  Pose T = start;
  const double stages[] = {2.0 * cloud_voxel, cloud_voxel, config_->refine_voxel};
  for (const double distance : std::span<const double>(stages).subspan(from_refined ? 1 : 0)) {
    localization::IcpOptions icp;
    icp.max_correspondence_distance = distance;
    icp.kernel_scale = distance / 9.0;
    icp.max_iterations = 30;
    icp.convergence = 1e-5;
    icp.min_correspondences = 50;
    const localization::IcpResult r = localization::align_point_to_point(source.icp, target_, T, icp);
    if (!r.enough_correspondences) break;  // keep the last good transform
    T = r.T_target_source;
  }
  return T;
}

RefinedClouds RefinementBase::finish(const RefinementSource& source, const Pose& T_after_icp) const {
  Pose T = T_after_icp;
  if (config_->surface_refinement && planes_) {
    // Point-to-point between two voxel-centre lattices locks them together (surface_refinement.hpp):
    // the last step puts the other session's voxels on the base's surface planes.
    const SurfaceRefinement refined = refine_on_surface(source.surface, *planes_, T, surface_config(*config_));
    if (refined.ok) T = refined.T_base_other;
  }
  const localization::AlignmentQuality quality =
      localization::alignment_quality(source.icp, target_, T, config_->inlier_distance);
  return {T, quality.inlier_fraction(), quality.inlier_rmse};
}

void winning_places(const AlignmentSession& other, const std::vector<VerifiedPair>& pairs,
                    const std::vector<std::size_t>& winners, std::optional<std::size_t> only_other_submap,
                    std::set<std::size_t>& base_places, std::set<std::size_t>& other_places) {
  for (const std::size_t i : winners) {
    if (only_other_submap && other.places[pairs[i].other_place].submap != *only_other_submap) continue;
    base_places.insert(pairs[i].base_place);
    other_places.insert(pairs[i].other_place);
  }
}

}  // namespace slamvdb::sessions
