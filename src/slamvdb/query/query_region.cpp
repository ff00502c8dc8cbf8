#include "slamvdb/query/query_region.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>

namespace slamvdb {

bool QueryRegion::contains(const Vec3d& p_world) const {
  if (box && !box->contains(p_world)) return false;
  if (!near) return true;
  const Vec3d d = p_world - near->centre;
  const double squared = near->horizontal ? d.head<2>().squaredNorm() : d.squaredNorm();
  return squared <= near->radius * near->radius;
}

Eigen::AlignedBox3d QueryRegion::bounds() const {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Eigen::AlignedBox3d out(Vec3d::Constant(-kInf), Vec3d::Constant(kInf));
  if (box) out = *box;
  if (near) {
    Vec3d lo = near->centre.array() - near->radius, hi = near->centre.array() + near->radius;
    if (near->horizontal) lo.z() = -kInf, hi.z() = kInf;
    out = out.intersection(Eigen::AlignedBox3d(lo, hi));  // empty when the box and the ball are apart
  }
  return out;
}

QueryRegion make_region(std::optional<std::span<const double>> bbox, std::optional<std::span<const double>> near,
                        std::optional<double> radius, const RegionFieldNames& names) {
  const auto all_finite = [](std::span<const double> v) {
    for (const double x : v)
      if (!std::isfinite(x)) return false;
    return true;
  };
  QueryRegion region;
  if (bbox) {
    const std::span<const double> b = *bbox;
    if (b.size() != 6 || !all_finite(b))
      throw RegionError(names.bbox, fmt::format("{} is six finite numbers xmin,ymin,zmin,xmax,ymax,zmax (got {} value{})",
                                                names.bbox, b.size(), b.size() == 1 ? "" : "s"));
    for (int axis = 0; axis < 3; ++axis)
      if (b[axis] > b[axis + 3])
        throw RegionError(names.bbox, fmt::format("{}: the {} minimum {} is above the maximum {}", names.bbox,
                                                  "xyz"[axis], b[axis], b[axis + 3]));
    region.box = Eigen::AlignedBox3d(Vec3d(b[0], b[1], b[2]), Vec3d(b[3], b[4], b[5]));
  }
  if (near) {
    const std::span<const double> c = *near;
    if ((c.size() != 2 && c.size() != 3) || !all_finite(c))
      throw RegionError(names.near, fmt::format("{} is x,y or x,y,z (finite numbers; got {} value{})", names.near,
                                                c.size(), c.size() == 1 ? "" : "s"));
    if (!radius) throw RegionError(names.radius, fmt::format("{} needs {}", names.near, names.radius));
    if (!std::isfinite(*radius) || !(*radius > 0))
      throw RegionError(names.radius, fmt::format("{} is a distance in metres > 0 (got {})", names.radius, *radius));
    region.near = QueryRegion::Near{Vec3d(c[0], c[1], c.size() == 3 ? c[2] : 0.0), c.size() == 2, *radius};
  } else if (radius) {
    throw RegionError(names.near, fmt::format("{} needs {} (the centre)", names.radius, names.near));
  }
  if (!region.box && !region.near)
    throw RegionError(names.bbox, fmt::format("a region is {}, or {} with {}", names.bbox, names.near, names.radius));
  return region;
}

}  // namespace slamvdb
