#include "slamvdb/synth/scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace slamvdb::synth {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}

Eigen::Vector3f terrain_albedo(uint16_t label) {
  switch (label) {
    case 1:
      return {0.55f, 0.43f, 0.29f};  // dirt
    case 3:
      return {0.33f, 0.53f, 0.21f};  // grass
    case 10:
      return {0.27f, 0.27f, 0.29f};  // asphalt
    case 23:
      return {0.69f, 0.67f, 0.64f};  // concrete
    case 31:
      return {0.38f, 0.45f, 0.50f};  // puddle: sky reflected in brown water
    case 33:
      return {0.33f, 0.25f, 0.17f};  // mud
    case 34:
      return {0.50f, 0.46f, 0.42f};  // rubble
    default:
      return {0.5f, 0.5f, 0.5f};
  }
}

Scene::Scene(Terrain terrain, std::vector<Primitive> objects, std::vector<TerrainPatch> patches)
    : terrain_(std::move(terrain)), objects_(std::move(objects)), patches_(std::move(patches)) {
  if (objects_.empty()) return;
  Eigen::AlignedBox2d box;
  for (const Primitive& p : objects_) {
    const Eigen::AlignedBox3d b = p.bounds();
    box.extend(b.min().head<2>());
    box.extend(b.max().head<2>());
    objects_top_ = std::max(objects_top_, b.max().z());
  }
  grid_origin_ = box.min();
  nx_ = static_cast<int>(std::floor(box.sizes().x() / cell_)) + 1;
  ny_ = static_cast<int>(std::floor(box.sizes().y() / cell_)) + 1;
  const std::size_t cells = static_cast<std::size_t>(nx_) * ny_;
  cell_top_.assign(cells, -std::numeric_limits<float>::infinity());
  std::vector<std::vector<uint32_t>> bins(cells);
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    const Eigen::AlignedBox3d b = objects_[i].bounds();
    const int x0 = static_cast<int>(std::floor((b.min().x() - grid_origin_.x()) / cell_));
    const int x1 = std::min(nx_ - 1, static_cast<int>(std::floor((b.max().x() - grid_origin_.x()) / cell_)));
    const int y0 = static_cast<int>(std::floor((b.min().y() - grid_origin_.y()) / cell_));
    const int y1 = std::min(ny_ - 1, static_cast<int>(std::floor((b.max().y() - grid_origin_.y()) / cell_)));
    for (int iy = y0; iy <= y1; ++iy) {
      for (int ix = x0; ix <= x1; ++ix) {
        bins[cell_index(ix, iy)].push_back(static_cast<uint32_t>(i));
        cell_top_[cell_index(ix, iy)] = std::max(cell_top_[cell_index(ix, iy)], static_cast<float>(b.max().z()));
      }
    }
  }
  offsets_.assign(cells + 1, 0);
  for (std::size_t c = 0; c < cells; ++c) offsets_[c + 1] = offsets_[c] + static_cast<uint32_t>(bins[c].size());
  indices_.reserve(offsets_.back());
  for (const auto& bin : bins) indices_.insert(indices_.end(), bin.begin(), bin.end());
}

Scene::ObjectHit Scene::raycast_objects(const Vec3d& o, const Vec3d& d, double t_max) const {
  ObjectHit best{kInf, -1};
  if (objects_.empty()) return best;
  // Clip the ray to the grid's footprint.
  double t0 = 0.0, t1 = t_max;
  for (int a = 0; a < 2; ++a) {
    const double lo = grid_origin_[a], hi = lo + (a == 0 ? nx_ : ny_) * cell_;
    if (std::abs(d[a]) < 1e-12) {
      if (o[a] < lo || o[a] >= hi) return best;
      continue;
    }
    double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  if (t0 >= t1) return best;

  // 2D digital differential analyser over the cells the ray's footprint crosses.
  int ix = std::clamp(static_cast<int>(std::floor((o.x() + t0 * d.x() - grid_origin_.x()) / cell_)), 0, nx_ - 1);
  int iy = std::clamp(static_cast<int>(std::floor((o.y() + t0 * d.y() - grid_origin_.y()) / cell_)), 0, ny_ - 1);
  const int step_x = d.x() > 0.0 ? 1 : -1, step_y = d.y() > 0.0 ? 1 : -1;
  const double dt_x = std::abs(d.x()) > 1e-12 ? cell_ / std::abs(d.x()) : kInf;
  const double dt_y = std::abs(d.y()) > 1e-12 ? cell_ / std::abs(d.y()) : kInf;
  double next_x =
      std::abs(d.x()) > 1e-12 ? (grid_origin_.x() + (ix + (step_x > 0 ? 1 : 0)) * cell_ - o.x()) / d.x() : kInf;
  double next_y =
      std::abs(d.y()) > 1e-12 ? (grid_origin_.y() + (iy + (step_y > 0 ? 1 : 0)) * cell_ - o.y()) / d.y() : kInf;
  double t = t0;
  while (true) {
    const double t_exit = std::min({next_x, next_y, t1});
    const std::size_t c = cell_index(ix, iy);
    if (offsets_[c] != offsets_[c + 1] && std::min(o.z() + t * d.z(), o.z() + t_exit * d.z()) <= cell_top_[c]) {
      for (uint32_t k = offsets_[c]; k < offsets_[c + 1]; ++k) {
        const double tk = objects_[indices_[k]].intersect(o, d);
        if (tk < best.t) best = {tk, static_cast<int>(indices_[k])};
      }
    }
    if (best.t <= t_exit || t_exit >= t1) break;
    if (d.z() >= 0.0 && o.z() + t_exit * d.z() > objects_top_) break;
    if (next_x < next_y) {
      ix += step_x;
      t = next_x;
      next_x += dt_x;
    } else {
      iy += step_y;
      t = next_y;
      next_y += dt_y;
    }
    if (ix < 0 || ix >= nx_ || iy < 0 || iy >= ny_) break;
  }
  if (best.t > t_max) best = {kInf, -1};
  return best;
}

std::optional<SceneHit> Scene::raycast(const Vec3d& origin, const Vec3d& dir, double max_range) const {
  const std::optional<double> ground = terrain_.raycast(origin, dir, max_range);
  const double limit = ground ? *ground : max_range;
  const ObjectHit object = raycast_objects(origin, dir, limit);
  SceneHit hit;
  if (object.index >= 0) {
    const Primitive& p = objects_[object.index];
    hit.range = object.t;
    hit.label = p.label;
    hit.normal = p.normal_at(origin + object.t * dir);
    hit.albedo = p.albedo;
    return hit;
  }
  if (!ground) return std::nullopt;
  const Vec3d p = origin + *ground * dir;
  hit.range = *ground;
  hit.label = terrain_.label(p.x(), p.y());
  hit.normal = terrain_.normal(p.x(), p.y());
  hit.albedo = terrain_albedo(hit.label);
  return hit;
}

std::vector<uint16_t> Scene::surface_classes_near(const Vec3d& p, double tolerance) const {
  std::vector<uint16_t> out;
  if (std::abs(p.z() - terrain_.height(p.x(), p.y())) <= tolerance) {
    // Near a patch border the ground within the tolerance can carry either class.
    for (const auto& [dx, dy] :
         {std::pair{0.0, 0.0}, {tolerance, 0.0}, {-tolerance, 0.0}, {0.0, tolerance}, {0.0, -tolerance}})
      out.push_back(terrain_.label(p.x() + dx, p.y() + dy));
  }
  for (const Primitive& o : objects_)
    if (std::abs(o.signed_distance(p)) <= tolerance) out.push_back(o.label);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<uint16_t> Scene::classes() const {
  std::vector<uint16_t> out = terrain_.labels_present();
  for (const Primitive& o : objects_) out.push_back(o.label);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace slamvdb::synth
