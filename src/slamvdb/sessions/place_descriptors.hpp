#pragma once
// Places of a session for alignment without a prior: a few points per submap, each with a
// ScanContext descriptor of the submap's occupied voxels around it. The submap's own voxels
// only (in its own frame), so a place's descriptor does not depend on how well the session's
// submaps agree with each other.
//
// Where a place sits. Two sessions quantise the same surfaces into different grids and cut
// their drives into submaps at different places, so a place must be found from the geometry,
// not from a grid: each place starts at a column of a coarse grid (the densest columns of the
// submap) and moves by mean shift (flat kernel, `shift_radius`) to a local mode of the occupied
// voxels' horizontal density. Occupied voxels stand for surface area, not for the sensor's
// sampling density, so the mode is where the same surfaces are, in either session, up to the
// part of the surroundings each saw.
#include <cstddef>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/localization/scan_context.hpp"

namespace slamvdb::sessions {

// One submap of a session as alignment sees it: its anchor and the centres of its occupied
// voxels in its own frame (z up, as every anchor is).
struct SessionSubmap {
  int id = 0;
  Pose T_world_submap = Pose::Identity();
  std::vector<Vec3f> occupied_submap;
};

struct PlaceConfig {
  double cloud_voxel = 0.5;       // metres: the submaps' voxels are thinned to this for places and ICP
  double seed_spacing = 10.0;     // metres: the grid of the mean-shift seeds
  double shift_radius = 15.0;     // metres: the mean-shift kernel
  double merge_distance = 5.0;    // metres: places whose modes are this close are one
  std::size_t max_places_per_submap = 8;
  std::size_t min_place_voxels = 400;  // thinned voxels within scan_context.max_radius
  double ground_quantile = 0.1;   // the place's ground level: this quantile of the heights around it
  localization::ScanContextConfig scan_context{.rings = 20, .sectors = 60, .max_radius = 30.0,
                                               .height_offset = 2.0, .search_ratio = 0.1};
  void validate() const;  // throws Error naming the setting
};

struct Place {
  std::size_t submap = 0;           // index into the session's submaps
  Vec3d centre_submap = Vec3d::Zero();  // submap frame; z at the place's ground level
  std::size_t voxels = 0;           // thinned voxels within scan_context.max_radius
  localization::ScanContext descriptor;
  // The place's frame: the submap's axes, origin at the centre.
  Pose T_submap_place() const {
    Pose T = Pose::Identity();
    T.translation() = centre_submap;
    return T;
  }
};

// The submap's voxels thinned to config.cloud_voxel (submap frame).
std::vector<Vec3d> thinned_cloud(const SessionSubmap& submap, const PlaceConfig& config);

// The places of every submap, in submap order (deterministic).
std::vector<Place> make_places(const std::vector<SessionSubmap>& submaps, const PlaceConfig& config);
// The same from the submaps' thinned clouds (thinned_cloud), one per submap.
std::vector<Place> make_places(const std::vector<std::vector<Vec3d>>& thinned_clouds, const PlaceConfig& config);

// Points of `cloud` (submap frame) within `radius` (horizontally) of the place, in the place frame.
std::vector<Vec3d> points_around(const std::vector<Vec3d>& cloud, const Place& place, double radius);

}  // namespace slamvdb::sessions
