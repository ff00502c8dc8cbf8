#pragma once
// A simulated off-road world: labelled terrain plus objects, with ray casting for the simulated
// LiDAR and camera. Objects are binned in a 2D grid so a ray only tests the cells it crosses.
#include <optional>
#include <vector>

#include "slamvdb/synth/primitives.hpp"
#include "slamvdb/synth/terrain.hpp"

namespace slamvdb::synth {

struct SceneHit {
  double range = 0.0;  // distance along the unit ray
  uint16_t label = 0;  // RELLIS-3D class id
  Vec3d normal = Vec3d::UnitZ();
  Eigen::Vector3f albedo = Eigen::Vector3f::Ones();
};

// Camera colour of a terrain class (a natural look, not the label palette).
Eigen::Vector3f terrain_albedo(uint16_t label);

class Scene {
 public:
  Scene(Terrain terrain, std::vector<Primitive> objects, std::vector<TerrainPatch> patches);

  // First surface along the unit ray `dir` within max_range, or nullopt (sky / no return).
  std::optional<SceneHit> raycast(const Vec3d& origin, const Vec3d& dir, double max_range) const;
  // Classes of every surface (terrain or object) within `tolerance` of p: the independent check
  // that a labelled point really lies on a surface of its class.
  std::vector<uint16_t> surface_classes_near(const Vec3d& p, double tolerance) const;
  std::vector<uint16_t> classes() const;  // sorted ids of every class on the terrain or an object

  const Terrain& terrain() const { return terrain_; }
  const std::vector<Primitive>& objects() const { return objects_; }
  const std::vector<TerrainPatch>& patches() const { return patches_; }

 private:
  struct ObjectHit {
    double t;
    int index;
  };
  ObjectHit raycast_objects(const Vec3d& o, const Vec3d& d, double t_max) const;
  std::size_t cell_index(int ix, int iy) const { return static_cast<std::size_t>(iy) * nx_ + ix; }

  Terrain terrain_;
  std::vector<Primitive> objects_;
  std::vector<TerrainPatch> patches_;
  // Object grid (compressed rows): objects of cell c are indices_[offsets_[c] .. offsets_[c+1]).
  Eigen::Vector2d grid_origin_ = Eigen::Vector2d::Zero();
  double cell_ = 4.0;
  int nx_ = 0, ny_ = 0;
  std::vector<uint32_t> offsets_, indices_;
  std::vector<float> cell_top_;  // highest object point in each cell
  double objects_top_ = -1e30;
};

}  // namespace slamvdb::synth
