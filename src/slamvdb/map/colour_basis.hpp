#pragma once
// The colour basis of an embedding space: three axes (the first principal components of a map's
// embeddings) mapped to red, green and blue. It is saved in the map (MapInfo::colour_basis), so a
// map is always drawn in the same colours, and a later map of the same embedding space can adopt
// an earlier map's basis (`slamvdb map --colour-basis EARLIER.svdb`) so that the same thing has the
// same colour in both. Pure data: fitting it is the exporter's business (io/map_export).
#include <Eigen/Core>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

struct ColourBasis {
  Eigen::VectorXf mean;                                 // dim
  Eigen::Matrix<float, 3, Eigen::Dynamic> components;   // 3 x dim unit axes, largest variance first
  Eigen::Array3f lo = Eigen::Array3f::Zero();           // projection that maps to channel 0 ...
  Eigen::Array3f hi = Eigen::Array3f::Ones();           // ... and to channel 255

  int dim() const { return static_cast<int>(mean.size()); }
  Rgb8 colour(const float* embedding) const;  // `embedding` has dim() floats
  // Throws Error unless it fits embeddings of `dim`: sizes, finite values, unit axes, lo <= hi.
  void validate(int dim) const;
};

}  // namespace slamvdb
