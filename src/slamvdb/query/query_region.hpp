#pragma once
// A region of the world a question is limited to (`query --bbox`, `--near --radius`, and the
// "region" of POST /api/query): an axis-aligned box, a ball (near x,y,z + radius), a vertical
// cylinder (near x,y + radius: distance in the ground plane, any height), or a box and a ball or
// cylinder together (a cell must lie in both). A cell is in the region when its centre is.
#include <Eigen/Geometry>
#include <optional>
#include <span>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/types.hpp"

namespace slamvdb {

struct QueryRegion {
  std::optional<Eigen::AlignedBox3d> box;
  struct Near {
    Vec3d centre = Vec3d::Zero();
    bool horizontal = false;  // given as x,y: the distance is measured in x and y only
    double radius = 0;
  };
  std::optional<Near> near;

  bool contains(const Vec3d& p_world) const;
  // A box that holds the region (a cylinder's is unbounded in z).
  Eigen::AlignedBox3d bounds() const;
};

// A region refused: `field` is the part at fault ("bbox", "near" or "radius"), for the caller to
// name its own way (the CLI's --bbox, the API's region.bbox).
class RegionError : public Error {
 public:
  RegionError(std::string field, const std::string& message) : Error(message), field_(std::move(field)) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

// The region of these parts, checked: bbox is 6 finite numbers xmin,ymin,zmin,xmax,ymax,zmax with
// min <= max on every axis; near is 2 or 3 finite numbers and comes with a radius (finite, > 0);
// at least one of bbox and near. `names` says how the caller calls each part in messages.
struct RegionFieldNames {
  std::string bbox = "bbox", near = "near", radius = "radius";
};
QueryRegion make_region(std::optional<std::span<const double>> bbox, std::optional<std::span<const double>> near,
                        std::optional<double> radius, const RegionFieldNames& names = {});

}  // namespace slamvdb
