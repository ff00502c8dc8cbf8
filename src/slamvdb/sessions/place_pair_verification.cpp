#include "slamvdb/sessions/place_pair_verification.hpp"

#include <tbb/parallel_for.h>

#include "slamvdb/localization/registration.hpp"
#include "slamvdb/localization/voxel_hash_map.hpp"

namespace slamvdb::sessions {

using localization::VoxelHashMap;

AlignmentSession::AlignmentSession(const std::vector<SessionSubmap>& s, const AlignmentConfig& config) : submaps(&s) {
  PlaceConfig dense = config.places;
  dense.cloud_voxel = config.refine_voxel;
  clouds.resize(s.size());
  std::vector<std::vector<Vec3d>> dense_submap_clouds(s.size());
  tbb::parallel_for(std::size_t{0}, s.size(), [&](std::size_t i) {
    clouds[i] = thinned_cloud(s[i], config.places);
    dense_submap_clouds[i] = thinned_cloud(s[i], dense);
  });
  for (const SessionSubmap& submap : s) T_world_submaps.push_back(submap.T_world_submap);
  dense_clouds = SubmapClouds(std::move(dense_submap_clouds));
  places = make_places(clouds, config.places);
}

namespace {

// The loop closer's consistency test with a prior in place of odometry.
bool agrees_with_prior(const VerifiedPair& pair, const AlignmentPrior& prior) {
  const Vec3d& x = pair.other_place_world;
  return (pair.T_base_other * x - prior.T_base_other * x).norm() <= prior.radius &&
         Eigen::AngleAxisd((prior.T_base_other.inverse() * pair.T_base_other).linear()).angle() <= prior.max_rotation;
}

}  // namespace

std::optional<PairRejection> verify_place_pair(const AlignmentSession& base, std::size_t base_place,
                                               const AlignmentSession& other, std::size_t other_place,
                                               const Pose& T_bplace_oplace_guess, PairGuess guess_kind,
                                               const AlignmentConfig& config, VerifiedPair& pair) {
  const double voxel = config.places.cloud_voxel;
  const double radius = config.places.scan_context.max_radius;
  // The base side reaches farther: the guess has no translation and the place centres of the
  // two sessions may be metres apart.
  // Five points per coarse voxel (the loop closer keeps 20): the coarse stages only have to bring
  // the guess within a metre, and every nearest-neighbour query reads 27 voxels' points.
  VoxelHashMap fine(voxel, 1e9, 20), dense(voxel, 1e9, 20);
  const std::vector<Vec3d> target = base.around(base_place, radius + 9.0 * voxel);
  fine.add_points(target);
  // The tests measure against the denser cloud (see max_rmse); ICP does not need it.
  dense.add_points(base.dense_around(base_place, radius + 9.0 * voxel));
  const std::vector<Vec3d> source = other.around(other_place, radius);
  std::optional<Pose> aligned;
  if (guess_kind == PairGuess::kDescriptor) {
    VoxelHashMap coarse(3.0 * voxel, 1e9, 5);
    coarse.add_points(target);
    aligned = localization::align_coarse_to_fine(source, coarse, fine, T_bplace_oplace_guess, voxel);
  } else {
    aligned = localization::align_fine(source, fine, T_bplace_oplace_guess, voxel);
  }
  if (!aligned) return PairRejection::kIcpFailed;
  const localization::AlignmentQuality quality =
      localization::alignment_quality(source, dense, *aligned, config.inlier_distance);
  pair.overlap = quality.inlier_fraction();
  pair.rmse = quality.inlier_rmse;
  if (pair.overlap < config.min_overlap) return PairRejection::kLowOverlap;
  if (pair.rmse > config.max_rmse) return PairRejection::kHighRmse;
  std::vector<Vec3d> structure;
  for (const Vec3d& p : source)
    if (p.z() > config.structure_height) structure.push_back(p);
  if (structure.size() < config.min_structure_voxels) return PairRejection::kTooLittleStructure;
  pair.structure_overlap =
      localization::alignment_quality(structure, dense, *aligned, config.inlier_distance).inlier_fraction();
  if (pair.structure_overlap < config.min_structure_overlap) return PairRejection::kLowStructureOverlap;
  pair.base_place = base_place;
  pair.other_place = other_place;
  pair.base_submap_id = (*base.submaps)[base.places[base_place].submap].id;
  pair.other_submap_id = (*other.submaps)[other.places[other_place].submap].id;
  pair.other_place_world = other.T_world_place(other_place).translation();
  pair.T_base_other = base.T_world_place(base_place) * *aligned * other.T_world_place(other_place).inverse();
  if (config.prior && !agrees_with_prior(pair, *config.prior)) return PairRejection::kAgainstPrior;
  return std::nullopt;
}

}  // namespace slamvdb::sessions
