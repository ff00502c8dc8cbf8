#pragma once
// Analytic solids the simulated objects are made of: ellipsoids (tree crowns, bushes, heads),
// capsules (trunks, poles, logs, bodies) and boxes turned about z (buildings, vehicles, barriers).
#include <Eigen/Geometry>
#include <cstdint>

#include "slamvdb/core/types.hpp"

namespace slamvdb::synth {

struct Primitive {
  enum class Shape : uint8_t { kEllipsoid, kCapsule, kBox };
  Shape shape = Shape::kEllipsoid;
  uint16_t label = 0;                                // RELLIS-3D class id
  Eigen::Vector3f albedo = Eigen::Vector3f::Ones();  // RGB in [0, 1], for the camera
  Vec3d a = Vec3d::Zero();                           // ellipsoid / box centre, capsule end
  Vec3d b = Vec3d::Ones();                           // ellipsoid radii, box half extents, capsule other end
  double radius = 0.0;                               // capsule
  double cos_yaw = 1.0, sin_yaw = 0.0;               // box heading

  static Primitive ellipsoid(uint16_t label, const Eigen::Vector3f& albedo, const Vec3d& centre, const Vec3d& radii);
  static Primitive capsule(uint16_t label, const Eigen::Vector3f& albedo, const Vec3d& end0, const Vec3d& end1,
                           double radius);
  static Primitive box(uint16_t label, const Eigen::Vector3f& albedo, const Vec3d& centre, const Vec3d& half_extents,
                       double yaw);

  Eigen::AlignedBox3d bounds() const;
  // Distance along the unit ray to the first surface crossing with t > 0, or +infinity.
  double intersect(const Vec3d& origin, const Vec3d& dir) const;
  Vec3d normal_at(const Vec3d& surface_point) const;  // outward unit normal
  // Signed distance (negative inside); exact for capsules and boxes, for ellipsoids a value whose
  // magnitude never exceeds the true distance.
  double signed_distance(const Vec3d& p) const;
};

}  // namespace slamvdb::synth
