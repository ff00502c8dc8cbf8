#include "slamvdb/synth/terrain.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "slamvdb/synth/random.hpp"

namespace slamvdb::synth {

bool TerrainPatch::contains(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d d = p - centre;
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double lx = (c * d.x() + s * d.y()) / half_size.x();
  const double ly = (-s * d.x() + c * d.y()) / half_size.y();
  if (shape == Shape::kRectangle) return std::abs(lx) <= 1.0 && std::abs(ly) <= 1.0;
  return lx * lx + ly * ly <= 1.0;
}

Eigen::AlignedBox2d TerrainPatch::bounds() const {
  const double r = half_size.norm();
  return {centre - Eigen::Vector2d::Constant(r), centre + Eigen::Vector2d::Constant(r)};
}

Terrain::Terrain(const Eigen::AlignedBox2d& extent, uint64_t seed, uint16_t ground_class) : extent_(extent) {
  const Eigen::Vector2d size = extent.sizes();
  hnx_ = static_cast<int>(std::ceil(size.x() / kHeightStep)) + 1;
  hny_ = static_cast<int>(std::ceil(size.y() / kHeightStep)) + 1;
  lnx_ = static_cast<int>(std::ceil(size.x() / kLabelStep));
  lny_ = static_cast<int>(std::ceil(size.y() / kLabelStep));

  // Wavelengths from a gentle swell down to small bumps; amplitudes keep each slope near 0.05.
  struct Wave {
    double amplitude, wavelength;
  };
  constexpr std::array<Wave, 6> kWaves = {
      {{1.0, 110.0}, {0.6, 60.0}, {0.3, 32.0}, {0.12, 14.0}, {0.05, 7.0}, {0.02, 3.5}}};
  Rng rng(seed, Stream::kTerrain, 0);
  std::array<Eigen::Vector3d, kWaves.size()> waves;  // (kx, ky, phase)
  for (std::size_t k = 0; k < kWaves.size(); ++k) {
    const double dir = rng.uniform(0.0, 2.0 * std::numbers::pi);
    const double kmag = 2.0 * std::numbers::pi / kWaves[k].wavelength;
    waves[k] = {kmag * std::cos(dir), kmag * std::sin(dir), rng.uniform(0.0, 2.0 * std::numbers::pi)};
  }
  heights_.resize(static_cast<std::size_t>(hnx_) * hny_);
  max_height_ = -1e30;
  for (int iy = 0; iy < hny_; ++iy) {
    for (int ix = 0; ix < hnx_; ++ix) {
      const double x = extent.min().x() + ix * kHeightStep, y = extent.min().y() + iy * kHeightStep;
      double h = 0.0;
      for (std::size_t k = 0; k < kWaves.size(); ++k)
        h += kWaves[k].amplitude * std::sin(waves[k].x() * x + waves[k].y() * y + waves[k].z());
      heights_[static_cast<std::size_t>(iy) * hnx_ + ix] = h;
    }
  }
  for (double h : heights_) max_height_ = std::max(max_height_, h);
  // On a bilinear patch |dh/dx| and |dh/dy| are bounded by its edges' differences. Per tile the
  // largest patch bound, then the largest over each tile's 3 x 3 neighbourhood.
  tnx_ = (hnx_ - 2) / kTileCells + 1;
  tny_ = (hny_ - 2) / kTileCells + 1;
  std::vector<double> tile(static_cast<std::size_t>(tnx_) * tny_, 0.0);
  for (int iy = 0; iy + 1 < hny_; ++iy) {
    for (int ix = 0; ix + 1 < hnx_; ++ix) {
      const double gx = std::max(std::abs(height_at(ix + 1, iy) - height_at(ix, iy)),
                                 std::abs(height_at(ix + 1, iy + 1) - height_at(ix, iy + 1)));
      const double gy = std::max(std::abs(height_at(ix, iy + 1) - height_at(ix, iy)),
                                 std::abs(height_at(ix + 1, iy + 1) - height_at(ix + 1, iy)));
      double& t = tile[static_cast<std::size_t>(iy / kTileCells) * tnx_ + ix / kTileCells];
      t = std::max(t, std::hypot(gx, gy) / kHeightStep);
    }
  }
  tile_lipschitz_.assign(tile.size(), 0.0);
  for (int ty = 0; ty < tny_; ++ty)
    for (int tx = 0; tx < tnx_; ++tx) {
      double& l = tile_lipschitz_[static_cast<std::size_t>(ty) * tnx_ + tx];
      for (int ny = std::max(0, ty - 1); ny <= std::min(tny_ - 1, ty + 1); ++ny)
        for (int nx = std::max(0, tx - 1); nx <= std::min(tnx_ - 1, tx + 1); ++nx)
          l = std::max(l, tile[static_cast<std::size_t>(ny) * tnx_ + nx]);
      lipschitz_ = std::max(lipschitz_, l);
    }
  labels_.assign(static_cast<std::size_t>(lnx_) * lny_, static_cast<uint8_t>(ground_class));
}

void Terrain::paint(const TerrainPatch& patch) {
  const Eigen::AlignedBox2d box = patch.bounds();
  const int x0 = std::max(0, static_cast<int>(std::floor((box.min().x() - extent_.min().x()) / kLabelStep)));
  const int y0 = std::max(0, static_cast<int>(std::floor((box.min().y() - extent_.min().y()) / kLabelStep)));
  const int x1 = std::min(lnx_ - 1, static_cast<int>(std::floor((box.max().x() - extent_.min().x()) / kLabelStep)));
  const int y1 = std::min(lny_ - 1, static_cast<int>(std::floor((box.max().y() - extent_.min().y()) / kLabelStep)));
  for (int iy = y0; iy <= y1; ++iy) {
    for (int ix = x0; ix <= x1; ++ix) {
      const Eigen::Vector2d p = extent_.min() + Eigen::Vector2d(ix + 0.5, iy + 0.5) * kLabelStep;
      if (patch.contains(p)) labels_[static_cast<std::size_t>(iy) * lnx_ + ix] = static_cast<uint8_t>(patch.label);
    }
  }
}

void Terrain::paint_disc(const Eigen::Vector2d& centre, double radius, uint16_t label) {
  paint({label, TerrainPatch::Shape::kEllipse, centre, Eigen::Vector2d::Constant(radius), 0.0});
}

double Terrain::local_lipschitz(double x, double y) const {
  const double tile = kTileCells * kHeightStep;
  const int tx = std::clamp(static_cast<int>(std::max(0.0, (x - extent_.min().x()) / tile)), 0, tnx_ - 1);
  const int ty = std::clamp(static_cast<int>(std::max(0.0, (y - extent_.min().y()) / tile)), 0, tny_ - 1);
  return tile_lipschitz_[static_cast<std::size_t>(ty) * tnx_ + tx];
}

Eigen::Vector2d Terrain::gradient(double x, double y) const {
  const Cell c = height_cell(x, y);
  const double h00 = height_at(c.ix, c.iy), h10 = height_at(c.ix + 1, c.iy);
  const double h01 = height_at(c.ix, c.iy + 1), h11 = height_at(c.ix + 1, c.iy + 1);
  return Eigen::Vector2d((h10 - h00) * (1.0 - c.fy) + (h11 - h01) * c.fy,
                         (h01 - h00) * (1.0 - c.fx) + (h11 - h10) * c.fx) /
         kHeightStep;
}

Vec3d Terrain::normal(double x, double y) const {
  const Eigen::Vector2d g = gradient(x, y);
  return Vec3d(-g.x(), -g.y(), 1.0).normalized();
}

uint16_t Terrain::label(double x, double y) const {
  const int ix = std::clamp(static_cast<int>(std::floor((x - extent_.min().x()) / kLabelStep)), 0, lnx_ - 1);
  const int iy = std::clamp(static_cast<int>(std::floor((y - extent_.min().y()) / kLabelStep)), 0, lny_ - 1);
  return labels_[static_cast<std::size_t>(iy) * lnx_ + ix];
}

std::optional<double> Terrain::raycast(const Vec3d& o, const Vec3d& d, double max_range) const {
  auto gap = [&](double t) { return o.z() + t * d.z() - height(o.x() + t * d.x(), o.y() + t * d.y()); };
  const double horizontal = std::sqrt(d.x() * d.x() + d.y() * d.y());
  double t = 0.0, g = gap(0.0);
  // The gap z - h(x, y) shrinks at most at L |d_xy| - d_z per unit of t; never, if that is <= 0.
  if (g <= 0.0 || lipschitz_ * horizontal - d.z() <= 0.0) return std::nullopt;
  // Steps use the local bound, so they must stay within the tile's neighbourhood.
  const double max_step = horizontal > 1e-9 ? kTileCells * kHeightStep / horizontal : max_range;
  double t_above = 0.0, g_above = g;
  while (true) {
    if (g < 1e-5) return t;
    if (d.z() >= 0.0 && o.z() + t * d.z() > max_height_) return std::nullopt;
    if (t >= max_range) return std::nullopt;
    const double closing = local_lipschitz(o.x() + t * d.x(), o.y() + t * d.y()) * horizontal - d.z();
    // Past the safe step by a little (relative to t): a miss that close is a graze within
    // millimetres, and the bracketing below finds the crossing when the step lands underground.
    const double safe = closing > 0.0 ? std::min(g / closing, max_step) : max_step;
    const double step = std::max(safe, 0.01 + 0.002 * t);
    t_above = t;
    g_above = g;
    t = std::min(t + step, max_range);
    g = gap(t);
    if (g < 0.0) break;
  }
  // Regula falsi (Illinois variant) on the bracket [t_above (above ground), t (below)].
  double ta = t_above, ga = g_above, tb = t, gb = g;
  int side = 0;
  for (int i = 0; i < 40; ++i) {
    const double tm = (ta * gb - tb * ga) / (gb - ga);
    const double gm = gap(tm);
    if (std::abs(gm) < 1e-6) return tm;
    if (gm > 0.0) {
      ta = tm;
      ga = gm;
      if (side == 1) gb *= 0.5;
      side = 1;
    } else {
      tb = tm;
      gb = gm;
      if (side == -1) ga *= 0.5;
      side = -1;
    }
  }
  return 0.5 * (ta + tb);
}

std::vector<uint16_t> Terrain::labels_present() const {
  std::array<bool, 256> seen{};
  for (uint8_t l : labels_) seen[l] = true;
  std::vector<uint16_t> out;
  for (int i = 0; i < 256; ++i)
    if (seen[i]) out.push_back(static_cast<uint16_t>(i));
  return out;
}

}  // namespace slamvdb::synth
