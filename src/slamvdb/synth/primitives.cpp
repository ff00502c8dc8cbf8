#include "slamvdb/synth/primitives.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace slamvdb::synth {

namespace {
constexpr double kNoHit = std::numeric_limits<double>::infinity();

// Box frame: centred, turned back by the yaw.
Vec3d to_box(const Primitive& p, const Vec3d& v) {
  return {p.cos_yaw * v.x() + p.sin_yaw * v.y(), -p.sin_yaw * v.x() + p.cos_yaw * v.y(), v.z()};
}
Vec3d from_box(const Primitive& p, const Vec3d& v) {
  return {p.cos_yaw * v.x() - p.sin_yaw * v.y(), p.sin_yaw * v.x() + p.cos_yaw * v.y(), v.z()};
}

double sphere_hit(const Vec3d& oc, const Vec3d& d, double r) {  // oc = origin - centre, |d| = 1
  const double b = oc.dot(d), c = oc.squaredNorm() - r * r;
  const double h = b * b - c;
  if (h < 0.0) return kNoHit;
  const double s = std::sqrt(h);
  const double t = -b - s;
  if (t > 0.0) return t;
  return -b + s > 0.0 ? -b + s : kNoHit;
}
}  // namespace

Primitive Primitive::ellipsoid(uint16_t label, const Eigen::Vector3f& albedo, const Vec3d& centre, const Vec3d& radii) {
  Primitive p;
  p.shape = Shape::kEllipsoid;
  p.label = label;
  p.albedo = albedo;
  p.a = centre;
  p.b = radii;
  return p;
}

Primitive Primitive::capsule(uint16_t label, const Eigen::Vector3f& albedo, const Vec3d& end0, const Vec3d& end1,
                             double radius) {
  Primitive p;
  p.shape = Shape::kCapsule;
  p.label = label;
  p.albedo = albedo;
  p.a = end0;
  p.b = end1;
  p.radius = radius;
  return p;
}

Primitive Primitive::box(uint16_t label, const Eigen::Vector3f& albedo, const Vec3d& centre, const Vec3d& half_extents,
                         double yaw) {
  Primitive p;
  p.shape = Shape::kBox;
  p.label = label;
  p.albedo = albedo;
  p.a = centre;
  p.b = half_extents;
  p.cos_yaw = std::cos(yaw);
  p.sin_yaw = std::sin(yaw);
  return p;
}

Eigen::AlignedBox3d Primitive::bounds() const {
  switch (shape) {
    case Shape::kEllipsoid:
      return {a - b, a + b};
    case Shape::kCapsule: {
      const Vec3d r = Vec3d::Constant(radius);
      return {a.cwiseMin(b) - r, a.cwiseMax(b) + r};
    }
    case Shape::kBox: {
      const double ex = std::abs(cos_yaw) * b.x() + std::abs(sin_yaw) * b.y();
      const double ey = std::abs(sin_yaw) * b.x() + std::abs(cos_yaw) * b.y();
      const Vec3d e(ex, ey, b.z());
      return {a - e, a + e};
    }
  }
  return {};
}

double Primitive::intersect(const Vec3d& o, const Vec3d& d) const {
  switch (shape) {
    case Shape::kEllipsoid: {
      // Scale space so the ellipsoid becomes the unit sphere; t is unchanged by the scaling.
      const Vec3d oc = (o - a).cwiseQuotient(b), ds = d.cwiseQuotient(b);
      const double aa = ds.squaredNorm(), bb = oc.dot(ds), cc = oc.squaredNorm() - 1.0;
      const double h = bb * bb - aa * cc;
      if (h < 0.0) return kNoHit;
      const double s = std::sqrt(h);
      const double t = (-bb - s) / aa;
      if (t > 0.0) return t;
      return (-bb + s) / aa > 0.0 ? (-bb + s) / aa : kNoHit;
    }
    case Shape::kCapsule: {
      // Infinite cylinder clipped to the segment, then the two end spheres (Quilez's method).
      const Vec3d ba = b - a, oa = o - a;
      const double baba = ba.squaredNorm(), bard = ba.dot(d), baoa = ba.dot(oa);
      const double rdoa = d.dot(oa), oaoa = oa.squaredNorm();
      const double qa = baba - bard * bard;
      double best = kNoHit;
      if (qa > 1e-12) {
        const double qb = baba * rdoa - baoa * bard;
        const double qc = baba * oaoa - baoa * baoa - radius * radius * baba;
        const double h = qb * qb - qa * qc;
        if (h >= 0.0) {
          const double t = (-qb - std::sqrt(h)) / qa;
          const double y = baoa + t * bard;
          if (t > 0.0 && y > 0.0 && y < baba) best = t;
        }
      }
      best = std::min(best, sphere_hit(oa, d, radius));
      best = std::min(best, sphere_hit(o - b, d, radius));
      return best;
    }
    case Shape::kBox: {
      const Vec3d ol = to_box(*this, o - a), dl = to_box(*this, d);
      double t_near = -kNoHit, t_far = kNoHit;
      for (int i = 0; i < 3; ++i) {
        if (std::abs(dl[i]) < 1e-15) {
          if (std::abs(ol[i]) > b[i]) return kNoHit;
          continue;
        }
        const double inv = 1.0 / dl[i];
        double t0 = (-b[i] - ol[i]) * inv, t1 = (b[i] - ol[i]) * inv;
        if (t0 > t1) std::swap(t0, t1);
        t_near = std::max(t_near, t0);
        t_far = std::min(t_far, t1);
      }
      if (t_near > t_far || t_far <= 0.0) return kNoHit;
      return t_near > 0.0 ? t_near : t_far;
    }
  }
  return kNoHit;
}

Vec3d Primitive::normal_at(const Vec3d& p) const {
  switch (shape) {
    case Shape::kEllipsoid:
      return (p - a).cwiseQuotient(b.cwiseProduct(b)).normalized();
    case Shape::kCapsule: {
      const Vec3d ba = b - a;
      const double s = std::clamp((p - a).dot(ba) / ba.squaredNorm(), 0.0, 1.0);
      return (p - (a + s * ba)).normalized();
    }
    case Shape::kBox: {
      const Vec3d l = to_box(*this, p - a);
      int axis = 0;  // the face the point is closest to
      double best = kNoHit;
      for (int i = 0; i < 3; ++i) {
        const double gap = std::abs(b[i] - std::abs(l[i]));
        if (gap < best) {
          best = gap;
          axis = i;
        }
      }
      Vec3d n = Vec3d::Zero();
      n[axis] = l[axis] >= 0.0 ? 1.0 : -1.0;
      return from_box(*this, n);
    }
  }
  return Vec3d::UnitZ();
}

double Primitive::signed_distance(const Vec3d& p) const {
  switch (shape) {
    case Shape::kEllipsoid: {
      // (|q| - 1) * r_min with q = (p - c) / r: zero on the surface and below the true distance.
      return ((p - a).cwiseQuotient(b).norm() - 1.0) * b.minCoeff();
    }
    case Shape::kCapsule: {
      const Vec3d ba = b - a;
      const double s = std::clamp((p - a).dot(ba) / ba.squaredNorm(), 0.0, 1.0);
      return (p - (a + s * ba)).norm() - radius;
    }
    case Shape::kBox: {
      const Vec3d q = to_box(*this, p - a).cwiseAbs() - b;
      return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
    }
  }
  return kNoHit;
}

}  // namespace slamvdb::synth
