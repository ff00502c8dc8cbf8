#pragma once
// Simulated uneven ground: a smooth height field (bilinear over a 0.5 m grid) carrying a class
// map (0.25 m grid) painted with terrain patches. Outside the grids the edge values continue.
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <optional>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::synth {

// A region of one terrain class: an ellipse or a rectangle with its own heading.
struct TerrainPatch {
  enum class Shape : uint8_t { kEllipse, kRectangle };
  uint16_t label = 0;
  Shape shape = Shape::kEllipse;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  Eigen::Vector2d half_size = Eigen::Vector2d::Ones();  // along the patch's own x and y axes
  double yaw = 0.0;

  bool contains(const Eigen::Vector2d& p) const;
  Eigen::AlignedBox2d bounds() const;
};

class Terrain {
 public:
  // Rolling ground (a sum of seeded sinusoids, slopes up to a few degrees) over `extent`,
  // every cell labelled `ground_class` until patches are painted.
  Terrain(const Eigen::AlignedBox2d& extent, uint64_t seed, uint16_t ground_class);

  void paint(const TerrainPatch& patch);
  void paint_disc(const Eigen::Vector2d& centre, double radius, uint16_t label);

  double height(double x, double y) const {
    const Cell c = height_cell(x, y);
    const double* row0 = &heights_[static_cast<std::size_t>(c.iy) * hnx_ + c.ix];
    const double* row1 = row0 + hnx_;
    return (row0[0] + (row0[1] - row0[0]) * c.fx) * (1.0 - c.fy) + (row1[0] + (row1[1] - row1[0]) * c.fx) * c.fy;
  }
  Eigen::Vector2d gradient(double x, double y) const;
  Vec3d normal(double x, double y) const;
  uint16_t label(double x, double y) const;
  // Distance along the unit ray `dir` to the ground, if within max_range. Sphere tracing with the
  // grid's Lipschitz bound (it never steps through the ground), then regula falsi on the crossing.
  std::optional<double> raycast(const Vec3d& origin, const Vec3d& dir, double max_range) const;

  double lipschitz() const { return lipschitz_; }  // bound on |grad h| anywhere
  std::vector<uint16_t> labels_present() const;    // sorted

 private:
  struct Cell {
    int ix, iy;
    double fx, fy;  // position inside the cell, [0, 1]
  };
  Cell height_cell(double x, double y) const {
    // Clamped first, so the truncating conversion is a floor and the edge values continue outside.
    const double u = std::clamp((x - extent_.min().x()) / kHeightStep, 0.0, hnx_ - 1.0);
    const double v = std::clamp((y - extent_.min().y()) / kHeightStep, 0.0, hny_ - 1.0);
    const int ix = std::min(static_cast<int>(u), hnx_ - 2), iy = std::min(static_cast<int>(v), hny_ - 2);
    return {ix, iy, u - ix, v - iy};
  }
  double height_at(int ix, int iy) const { return heights_[static_cast<std::size_t>(iy) * hnx_ + ix]; }
  // Bound on |grad h| over the tile holding (x, y) and its eight neighbours.
  double local_lipschitz(double x, double y) const;

  Eigen::AlignedBox2d extent_;
  static constexpr double kHeightStep = 0.5, kLabelStep = 0.25;  // powers of two: divisions become products
  int hnx_ = 0, hny_ = 0, lnx_ = 0, lny_ = 0;
  std::vector<double> heights_;
  static constexpr int kTileCells = 16;  // 8 m tiles of height cells
  int tnx_ = 0, tny_ = 0;
  std::vector<double> tile_lipschitz_;
  std::vector<uint8_t> labels_;
  double max_height_ = 0.0, lipschitz_ = 0.0;
};

}  // namespace slamvdb::synth
