#include "slamvdb/fleet/fleet_summary.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace slamvdb::fleet {
namespace {

double cap_angle_between_units(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0));
}

}  // namespace

std::optional<EmbeddingCap> embedding_cap(const SemanticLayer& layer) {
  const auto dim = static_cast<Eigen::Index>(layer.dim());
  std::vector<Eigen::VectorXd> units;
  units.reserve(layer.size());
  Eigen::VectorXf decoded(dim);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(dim);
  layer.for_each([&](SemanticLayer::Handle h) {
    layer.read(h, decoded.data());
    const Eigen::VectorXd e = decoded.cast<double>();
    const double norm = e.norm();
    if (!(norm > 0) || !std::isfinite(norm)) return;
    units.push_back(e / norm);
    sum += units.back();
  });
  const double sum_norm = sum.norm();
  if (units.empty() || !(sum_norm > 0)) return std::nullopt;
  const Eigen::VectorXd centre = sum / sum_norm;
  EmbeddingCap cap;
  cap.centroid.assign(centre.data(), centre.data() + dim);
  // The radius is measured from the stored (float) centroid, as cap_cosine_bound reads it: then it
  // does not depend on the order the voxels were summed in (a submap in memory while mapping and
  // the same submap read back from its file iterate differently; the double sums differ in the last
  // bit, the float centroid and each voxel's angle do not), so `map --push` and `push` of the file
  // store the same summary.
  const Eigen::VectorXd stored = Eigen::Map<const Eigen::VectorXf>(cap.centroid.data(), dim).cast<double>();
  const Eigen::VectorXd stored_unit = stored / stored.norm();
  for (const Eigen::VectorXd& u : units) cap.radius = std::max(cap.radius, cap_angle_between_units(stored_unit, u));
  return cap;
}

std::optional<EmbeddingCap> enclosing_cap(std::span<const EmbeddingCap> caps) {
  if (caps.empty()) return std::nullopt;
  const auto dim = static_cast<Eigen::Index>(caps.front().centroid.size());
  // Summaries of different lengths (a damaged row) enclose nothing: no bound, the group is scored.
  for (const EmbeddingCap& c : caps)
    if (static_cast<Eigen::Index>(c.centroid.size()) != dim) return std::nullopt;
  const auto as_unit = [](const EmbeddingCap& c) {
    const Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXf>(c.centroid.data(), static_cast<Eigen::Index>(c.centroid.size())).cast<double>();
    return Eigen::VectorXd(v / v.norm());
  };
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(dim);
  for (const EmbeddingCap& c : caps) sum += as_unit(c);
  if (!(sum.norm() > 0)) return std::nullopt;
  const Eigen::VectorXd centre = sum / sum.norm();
  EmbeddingCap out;
  for (const EmbeddingCap& c : caps) out.radius = std::max(out.radius, cap_angle_between_units(centre, as_unit(c)) + c.radius);
  out.radius = std::min(out.radius, std::numbers::pi);
  out.centroid.assign(centre.data(), centre.data() + dim);
  return out;
}

double cap_cosine_bound(const EmbeddingCap& cap, const Eigen::VectorXf& q) {
  if (cap.radius >= std::numbers::pi / 2 || static_cast<Eigen::Index>(cap.centroid.size()) != q.size()) return 1.0;
  const Eigen::VectorXd c = Eigen::Map<const Eigen::VectorXf>(cap.centroid.data(), q.size()).cast<double>();
  const Eigen::VectorXd u = q.cast<double>();
  const double angle = cap_angle_between_units(c / c.norm(), u / u.norm());
  return std::min(1.0, std::cos(std::max(0.0, angle - cap.radius)) + kCapBoundMargin);
}

}  // namespace slamvdb::fleet
