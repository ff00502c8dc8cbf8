#include "slamvdb/synth/scene_layout.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>

#include "slamvdb/synth/random.hpp"

namespace slamvdb::synth {

namespace {

// RELLIS-3D class ids (core/ontology.hpp).
enum Class : uint16_t {
  kDirt = 1,
  kGrass = 3,
  kTree = 4,
  kPole = 5,
  kVehicle = 8,
  kAsphalt = 10,
  kBuilding = 12,
  kLog = 15,
  kPerson = 17,
  kFence = 18,
  kBush = 19,
  kConcrete = 23,
  kBarrier = 27,
  kPuddle = 31,
  kMud = 33,
  kRubble = 34
};

constexpr double kTrailHalfWidth = 3.0;

double heading_at(const LoopPath& path, double s) {
  const Eigen::Vector2d t = path.tangent(s);
  return std::atan2(t.y(), t.x());
}

// Places objects without overlaps and off the trail, and builds their primitives.
class Layout {
 public:
  Layout(const LoopPath& path, const Terrain& terrain, uint64_t seed)
      : path_(path), terrain_(terrain), rng_(seed, Stream::kLayout, 0) {}

  Rng& rng() { return rng_; }
  double ground(const Eigen::Vector2d& p) const { return terrain_.height(p.x(), p.y()); }

  // True (and the footprint reserved) if a disc of `radius` at p keeps `trail_gap` from the
  // trail's edge and does not overlap anything placed before.
  bool reserve(const Eigen::Vector2d& p, double radius, double trail_gap) {
    for (const Disc& d : reserved_)
      if ((d.centre - p).norm() < d.radius + radius) return false;
    if (path_.distance(p) < kTrailHalfWidth + trail_gap + radius) return false;
    reserved_.push_back({p, radius});
    return true;
  }
  // Reserves a footprint for a hand-placed object, whatever is near.
  void block(const Eigen::Vector2d& p, double radius) { reserved_.push_back({p, radius}); }
  // True if a footprint of `radius` at p leaves the vehicle's way free along the WHOLE loop. A
  // hand-placed object sits beside one point of the path, but on a short loop another stretch
  // can pass there (seed 3 of a 100 m loop drove through the yard's building: the LiDAR saw
  // only walls within 3 m and odometry lost track); such an object is left out.
  bool clear_of_path(const Eigen::Vector2d& p, double radius) const {
    constexpr double kVehicleClearance = 1.5;  // vehicle half width plus a margin, metres
    return path_.distance(p) >= radius + kVehicleClearance;
  }
  void add(const Primitive& p) { objects_.push_back(p); }
  std::vector<Primitive> take_objects() { return std::move(objects_); }

  // A box standing on the ground, sunk below its lowest footprint corner so slopes leave no gap.
  void add_box_on_ground(uint16_t label, const Eigen::Vector3f& albedo, const Eigen::Vector2d& c,
                         const Eigen::Vector2d& half, double height, double yaw, double lift = 0.0) {
    const Eigen::Vector2d ax(std::cos(yaw), std::sin(yaw)), ay(-std::sin(yaw), std::cos(yaw));
    double lo = ground(c), hi = lo;
    for (int sx = -1; sx <= 1; sx += 2)
      for (int sy = -1; sy <= 1; sy += 2) {
        const double h = ground(c + sx * half.x() * ax + sy * half.y() * ay);
        lo = std::min(lo, h);
        hi = std::max(hi, h);
      }
    const double bottom = lift > 0.0 ? ground(c) + lift : lo - 0.3;
    const double top = (lift > 0.0 ? ground(c) : hi) + lift + height;
    add(Primitive::box(label, albedo, Vec3d(c.x(), c.y(), 0.5 * (bottom + top)),
                       Vec3d(half.x(), half.y(), 0.5 * (top - bottom)), yaw));
  }

  void add_vehicle(const Eigen::Vector2d& c, double yaw, const Eigen::Vector3f& paint) {
    const Eigen::Vector2d ax(std::cos(yaw), std::sin(yaw)), ay(-std::sin(yaw), std::cos(yaw));
    const double g = ground(c);
    add(Primitive::box(kVehicle, paint, Vec3d(c.x(), c.y(), g + 0.85), Vec3d(2.3, 0.95, 0.45), yaw));
    const Eigen::Vector2d cabin = c - 0.3 * ax;
    add(Primitive::box(kVehicle, paint * 0.8f, Vec3d(cabin.x(), cabin.y(), g + 1.62), Vec3d(1.2, 0.85, 0.33), yaw));
    const Eigen::Vector3f tyre(0.08f, 0.08f, 0.09f);
    for (int sx = -1; sx <= 1; sx += 2)
      for (int sy = -1; sy <= 1; sy += 2) {
        const Eigen::Vector2d w = c + sx * 1.5 * ax;
        const Eigen::Vector2d w0 = w + sy * 0.7 * ay, w1 = w + sy * 0.95 * ay;
        const double z = ground(w) + 0.38;
        add(Primitive::capsule(kVehicle, tyre, Vec3d(w0.x(), w0.y(), z), Vec3d(w1.x(), w1.y(), z), 0.38));
      }
  }

  void add_person(const Eigen::Vector2d& c, const Eigen::Vector3f& clothes) {
    const double g = ground(c);
    add(Primitive::capsule(kPerson, clothes, Vec3d(c.x(), c.y(), g + 0.22), Vec3d(c.x(), c.y(), g + 1.38), 0.21));
    add(Primitive::ellipsoid(kPerson, Eigen::Vector3f(0.80f, 0.62f, 0.48f), Vec3d(c.x(), c.y(), g + 1.66),
                             Vec3d(0.11, 0.11, 0.13)));
  }

  void add_tree(const Eigen::Vector2d& c, double crown_radius) {
    const double g = ground(c);
    const double trunk_height = rng_.uniform(1.8, 3.5), crown_half_height = rng_.uniform(1.8, 3.5);
    const float shade = static_cast<float>(rng_.uniform(0.8, 1.15));
    add(Primitive::capsule(kTree, Eigen::Vector3f(0.34f, 0.25f, 0.17f), Vec3d(c.x(), c.y(), g - 0.5),
                           Vec3d(c.x(), c.y(), g + trunk_height + crown_half_height), rng_.uniform(0.15, 0.3)));
    add(Primitive::ellipsoid(kTree, Eigen::Vector3f(0.15f, 0.36f, 0.12f) * shade,
                             Vec3d(c.x(), c.y(), g + trunk_height + crown_half_height),
                             Vec3d(crown_radius, crown_radius, crown_half_height)));
  }

 private:
  struct Disc {
    Eigen::Vector2d centre;
    double radius;
  };
  const LoopPath& path_;
  const Terrain& terrain_;
  Rng rng_;
  std::vector<Disc> reserved_;
  std::vector<Primitive> objects_;
};

}  // namespace

Scene build_offroad_scene(const LoopPath& path, uint64_t seed) {
  const double P = path.perimeter();
  Eigen::AlignedBox2d extent = path.bounds();
  extent.extend(extent.min() - Eigen::Vector2d::Constant(120.0));
  extent.extend(extent.max() + Eigen::Vector2d::Constant(120.0));
  Terrain terrain(extent, seed, kGrass);
  Layout layout(path, terrain, seed);
  Rng& rng = layout.rng();
  std::vector<TerrainPatch> patches;
  auto patch_along = [&](uint16_t label, TerrainPatch::Shape shape, double s, double lateral, double half_along,
                         double half_across, double yaw_offset = 0.0) {
    patches.push_back({label, shape, path.at(s, lateral), Eigen::Vector2d(half_along, half_across),
                       heading_at(path, s) + yaw_offset});
  };
  using Shape = TerrainPatch::Shape;

  // Bare dirt clearings in the grass fields.
  for (int i = 0; i < 4; ++i) {
    const double side = i % 2 == 0 ? 1.0 : -1.0;
    patch_along(kDirt, Shape::kEllipse, (0.2 + 0.2 * i) * P, side * rng.uniform(16.0, 30.0), rng.uniform(6.0, 12.0),
                rng.uniform(4.0, 8.0), rng.uniform(-1.0, 1.0));
  }
  for (const auto& p : patches) terrain.paint(p);
  // The trail: asphalt around the start and the building, dirt for the rest of the loop.
  const auto trail_class = [&](double s) { return (s < 0.3 * P || s > 0.96 * P) ? kAsphalt : kDirt; };
  for (double s = 0.0; s < P; s += 0.25) terrain.paint_disc(path.point(s), kTrailHalfWidth, trail_class(s));

  std::vector<TerrainPatch> trail_patches;
  const double yard = 0.07 * P;  // the building's concrete yard beside the asphalt
  trail_patches.push_back(
      {kConcrete, Shape::kRectangle, path.at(yard, -10.0), Eigen::Vector2d(13.0, 6.0), heading_at(path, yard)});
  trail_patches.push_back({kRubble, Shape::kEllipse, path.at(yard + 17.0, -12.0), Eigen::Vector2d(6.0, 4.0),
                           heading_at(path, yard + 17.0) + 0.4});
  trail_patches.push_back(
      {kRubble, Shape::kEllipse, path.at(0.68 * P, 6.0), Eigen::Vector2d(4.5, 2.5), heading_at(path, 0.68 * P)});
  for (double f : {0.42, 0.58, 0.78, 0.9}) {
    const double s = f * P, lateral = rng.uniform(-1.0, 1.0);
    const double along = rng.uniform(5.0, 8.0), across = rng.uniform(3.5, 4.5);
    trail_patches.push_back({kMud, Shape::kEllipse, path.at(s, lateral), Eigen::Vector2d(along, across),
                             heading_at(path, s) + rng.uniform(-0.3, 0.3)});
    const double ps = s + rng.uniform(-2.0, 2.0);
    trail_patches.push_back({kPuddle, Shape::kEllipse, path.at(ps, lateral + rng.uniform(-0.8, 0.8)),
                             Eigen::Vector2d(rng.uniform(2.0, 3.0), rng.uniform(1.2, 1.8)),
                             heading_at(path, ps) + rng.uniform(-0.5, 0.5)});
  }
  for (const auto& p : trail_patches) terrain.paint(p);
  patches.insert(patches.end(), trail_patches.begin(), trail_patches.end());

  // The yard: building behind the concrete pad, parked vehicles, barriers along the pad's edge.
  const double yard_heading = heading_at(path, yard);
  layout.block(path.at(yard, -10.0), 13.0);
  layout.block(path.at(yard, -22.0), 9.5);
  if (layout.clear_of_path(path.at(yard, -22.0), 9.5))
    layout.add_box_on_ground(kBuilding, Eigen::Vector3f(0.70f, 0.58f, 0.48f), path.at(yard, -22.0),
                             Eigen::Vector2d(8.0, 5.0), 6.5, yard_heading);
  if (layout.clear_of_path(path.at(yard - 7.0, -10.5), 2.6))
    layout.add_vehicle(path.at(yard - 7.0, -10.5), heading_at(path, yard - 7.0) + 0.5 * std::numbers::pi,
                       Eigen::Vector3f(0.12f, 0.22f, 0.55f));
  if (layout.clear_of_path(path.at(yard + 1.0, -10.5), 2.6))
    layout.add_vehicle(path.at(yard + 1.0, -10.5), heading_at(path, yard + 1.0) + 0.5 * std::numbers::pi,
                       Eigen::Vector3f(0.82f, 0.82f, 0.84f));
  if (layout.clear_of_path(path.at(yard + 6.0, -8.0), 0.4))
    layout.add_person(path.at(yard + 6.0, -8.0), Eigen::Vector3f(0.75f, 0.15f, 0.12f));
  for (int i = 0; i < 5; ++i) {
    const double s = yard + 3.0 + 2.3 * i;
    if (layout.clear_of_path(path.at(s, -4.6), 1.1))
      layout.add_box_on_ground(kBarrier, Eigen::Vector3f(0.95f, 0.52f, 0.15f), path.at(s, -4.6),
                               Eigen::Vector2d(1.0, 0.3), 0.8, heading_at(path, s));
  }
  // A shed across the loop, another vehicle and people by the dirt trail.
  const double shed = 0.55 * P;
  layout.block(path.at(shed, 20.0), 5.5);
  if (layout.clear_of_path(path.at(shed, 20.0), 5.5))
    layout.add_box_on_ground(kBuilding, Eigen::Vector3f(0.55f, 0.45f, 0.40f), path.at(shed, 20.0),
                             Eigen::Vector2d(4.0, 3.0), 3.5, heading_at(path, shed) + 0.3);
  layout.block(path.at(0.5 * P, 6.5), 2.6);
  if (layout.clear_of_path(path.at(0.5 * P, 6.5), 2.6))
    layout.add_vehicle(path.at(0.5 * P, 6.5), heading_at(path, 0.5 * P), Eigen::Vector3f(0.22f, 0.30f, 0.18f));
  for (double f : {0.47, 0.82}) {
    const double lateral = f < 0.5 ? 4.6 : -4.8;
    layout.block(path.at(f * P, lateral), 0.4);
    if (layout.clear_of_path(path.at(f * P, lateral), 0.4))
      layout.add_person(path.at(f * P, lateral),
                        f < 0.5 ? Eigen::Vector3f(0.20f, 0.35f, 0.70f) : Eigen::Vector3f(0.85f, 0.75f, 0.10f));
  }
  for (int i = 0; i < 4; ++i) {  // a second row of barriers closing a side track
    const double s = 0.93 * P + 2.3 * i;
    layout.block(path.at(s, 4.6), 1.1);
    if (layout.clear_of_path(path.at(s, 4.6), 1.1))
      layout.add_box_on_ground(kBarrier, Eigen::Vector3f(0.92f, 0.90f, 0.86f), path.at(s, 4.6),
                               Eigen::Vector2d(1.0, 0.3), 0.8, heading_at(path, s));
  }
  // Utility poles along the asphalt, outside the loop.
  for (double s = 5.0; s < 0.3 * P; s += 22.0) {
    const Eigen::Vector2d c = path.at(s, -5.5);
    if (!layout.reserve(c, 0.5, 1.0)) continue;
    const double g = layout.ground(c);
    layout.add(Primitive::capsule(kPole, Eigen::Vector3f(0.42f, 0.35f, 0.27f), Vec3d(c.x(), c.y(), g - 0.3),
                                  Vec3d(c.x(), c.y(), g + 7.0), 0.14));
  }
  // A post-and-rail fence following the dirt trail.
  {
    Eigen::Vector2d prev;
    double prev_ground = 0.0;
    bool have_prev = false;
    for (double s = 0.32 * P; s < 0.32 * P + 45.0; s += 2.5) {
      const Eigen::Vector2d c = path.at(s, -7.5);
      if (!layout.reserve(c, 0.7, 1.0)) {
        have_prev = false;
        continue;
      }
      const double g = layout.ground(c);
      const Eigen::Vector3f wood(0.55f, 0.47f, 0.38f);
      layout.add(Primitive::capsule(kFence, wood, Vec3d(c.x(), c.y(), g - 0.2), Vec3d(c.x(), c.y(), g + 1.3), 0.07));
      if (have_prev) {
        const Eigen::Vector2d mid = 0.5 * (prev + c), d = c - prev;
        const double gm = 0.5 * (g + prev_ground);
        for (double rail : {0.5, 1.1})
          layout.add(Primitive::box(kFence, wood, Vec3d(mid.x(), mid.y(), gm + rail), Vec3d(0.5 * d.norm(), 0.03, 0.06),
                                    std::atan2(d.y(), d.x())));
      }
      prev = c;
      prev_ground = g;
      have_prev = true;
    }
  }
  // Fallen logs beside the dirt trail.
  for (int placed = 0, tries = 0; placed < 5 && tries < 200; ++tries) {
    const double s = rng.uniform(0.33, 0.95) * P;
    const double lateral = (rng.uniform() < 0.5 ? -1.0 : 1.0) * rng.uniform(5.0, 8.0);
    const double length = rng.uniform(3.0, 5.0), radius = rng.uniform(0.18, 0.3);
    const double yaw = heading_at(path, s) + rng.uniform(-0.5, 0.5);
    const Eigen::Vector2d c = path.at(s, lateral);
    if (!layout.reserve(c, 0.5 * length + radius, 0.5)) continue;
    const Eigen::Vector2d half = 0.5 * length * Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
    const Eigen::Vector2d e0 = c - half, e1 = c + half;
    layout.add(Primitive::capsule(kLog, Eigen::Vector3f(0.42f, 0.30f, 0.20f),
                                  Vec3d(e0.x(), e0.y(), layout.ground(e0) + 0.7 * radius),
                                  Vec3d(e1.x(), e1.y(), layout.ground(e1) + 0.7 * radius), radius));
    ++placed;
  }
  // Trees and bushes in the fields on both sides.
  const int trees = static_cast<int>(0.5 * P), bushes = static_cast<int>(0.35 * P);
  for (int placed = 0, tries = 0; placed < trees && tries < 20 * trees; ++tries) {
    const double crown = rng.uniform(1.5, 3.0);
    const double lateral = (rng.uniform() < 0.5 ? -1.0 : 1.0) * rng.uniform(5.0, 45.0);
    const Eigen::Vector2d c = path.at(rng.uniform(0.0, P), lateral);
    if (!layout.reserve(c, crown, 1.0)) continue;
    layout.add_tree(c, crown);
    ++placed;
  }
  for (int placed = 0, tries = 0; placed < bushes && tries < 20 * bushes; ++tries) {
    const double r = rng.uniform(0.6, 1.4), half_height = rng.uniform(0.5, 1.0);
    const double lateral = (rng.uniform() < 0.5 ? -1.0 : 1.0) * rng.uniform(4.0, 30.0);
    const Eigen::Vector2d c = path.at(rng.uniform(0.0, P), lateral);
    if (!layout.reserve(c, r, 0.5)) continue;
    const float shade = static_cast<float>(rng.uniform(0.85, 1.15));
    layout.add(Primitive::ellipsoid(kBush, Eigen::Vector3f(0.40f, 0.44f, 0.18f) * shade,
                                    Vec3d(c.x(), c.y(), layout.ground(c) + 0.5 * half_height),
                                    Vec3d(r, r, half_height)));
    ++placed;
  }
  return Scene(std::move(terrain), layout.take_objects(), std::move(patches));
}

Scene build_repeated_places_scene(const LoopPath& path, uint64_t seed, double spacing) {
  const double P = path.perimeter();
  Eigen::AlignedBox2d extent = path.bounds();
  extent.extend(extent.min() - Eigen::Vector2d::Constant(120.0));
  extent.extend(extent.max() + Eigen::Vector2d::Constant(120.0));
  Terrain terrain(extent, seed, kGrass);
  for (double s = 0.0; s < P; s += 0.25) terrain.paint_disc(path.point(s), kTrailHalfWidth, kDirt);
  Layout layout(path, terrain, seed);
  // The module, in the trail's frame (along, lateral): identical at every repetition.
  for (double s0 = 0.5 * spacing; s0 + spacing < P; s0 += spacing) {
    const auto at = [&](double along, double lateral) { return path.at(s0 + along, lateral); };
    const double heading = heading_at(path, s0);
    layout.add_box_on_ground(kBuilding, Eigen::Vector3f(0.6f, 0.5f, 0.45f), at(0.0, -12.0), Eigen::Vector2d(4.0, 3.0),
                             3.5, heading);
    layout.add_vehicle(at(6.0, 7.0), heading, Eigen::Vector3f(0.3f, 0.3f, 0.35f));
    for (const auto& [along, lateral] : {std::pair{-6.0, 9.0}, std::pair{3.0, 14.0}, std::pair{-9.0, -8.0}}) {
      const Eigen::Vector2d c = at(along, lateral);
      const double g = layout.ground(c);
      layout.add(Primitive::capsule(kTree, Eigen::Vector3f(0.34f, 0.25f, 0.17f), Vec3d(c.x(), c.y(), g - 0.5),
                                    Vec3d(c.x(), c.y(), g + 5.5), 0.25));
      layout.add(Primitive::ellipsoid(kTree, Eigen::Vector3f(0.15f, 0.36f, 0.12f), Vec3d(c.x(), c.y(), g + 5.5),
                                      Vec3d(2.2, 2.2, 2.5)));
    }
    const Eigen::Vector2d pole = at(-3.0, -5.5);
    layout.add(Primitive::capsule(kPole, Eigen::Vector3f(0.42f, 0.35f, 0.27f),
                                  Vec3d(pole.x(), pole.y(), layout.ground(pole) - 0.3),
                                  Vec3d(pole.x(), pole.y(), layout.ground(pole) + 7.0), 0.14));
    for (int i = 0; i < 3; ++i)
      layout.add_box_on_ground(kBarrier, Eigen::Vector3f(0.95f, 0.52f, 0.15f), at(2.0 + 2.3 * i, -4.6),
                               Eigen::Vector2d(1.0, 0.3), 0.8, heading_at(path, s0 + 2.0 + 2.3 * i));
  }
  return Scene(std::move(terrain), layout.take_objects(), {});
}

}  // namespace slamvdb::synth
