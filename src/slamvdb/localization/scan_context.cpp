#include "slamvdb/localization/scan_context.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <nanoflann.hpp>
#include <numbers>

#include "slamvdb/core/error.hpp"

namespace slamvdb::localization {

void ScanContextConfig::validate() const {
  if (rings < 1 || sectors < 4 || !(max_radius > 0.0) || !(search_ratio >= 0.0 && search_ratio <= 0.5))
    throw Error(fmt::format("invalid ScanContext setting: {} rings, {} sectors, radius {} m, search ratio {}", rings,
                            sectors, max_radius, search_ratio));
}

ScanContext make_scan_context(const std::vector<Vec3d>& points, const ScanContextConfig& config) {
  ScanContext sc;
  sc.descriptor = Eigen::MatrixXf::Zero(config.rings, config.sectors);
  const double ring_width = config.max_radius / config.rings;
  const double sector_width = 2.0 * std::numbers::pi / config.sectors;
  for (const Vec3d& p : points) {
    if (!p.allFinite()) continue;
    const double r = std::hypot(p.x(), p.y());
    if (r >= config.max_radius || r <= 0.0) continue;
    double azimuth = std::atan2(p.y(), p.x());
    if (azimuth < 0.0) azimuth += 2.0 * std::numbers::pi;
    const int ring = std::min(static_cast<int>(r / ring_width), config.rings - 1);
    const int sector = std::min(static_cast<int>(azimuth / sector_width), config.sectors - 1);
    float& bin = sc.descriptor(ring, sector);
    bin = std::max(bin, static_cast<float>(p.z() + config.height_offset));
  }
  sc.ring_key = sc.descriptor.rowwise().mean();
  sc.sector_key = sc.descriptor.colwise().mean().transpose();
  return sc;
}

namespace {

// Mean over sectors (non-empty in both) of 1 - cosine similarity, query sector j against
// candidate sector j + shift.
double shifted_distance(const Eigen::MatrixXf& q, const Eigen::MatrixXf& c, int shift) {
  const int n = static_cast<int>(q.cols());
  double sum = 0.0;
  int used = 0;
  for (int j = 0; j < n; ++j) {
    const auto a = q.col(j);
    const auto b = c.col(((j + shift) % n + n) % n);
    const double na = a.norm(), nb = b.norm();
    if (na == 0.0 || nb == 0.0) continue;
    sum += a.dot(b) / (na * nb);
    ++used;
  }
  return used == 0 ? 1.0 : 1.0 - sum / used;
}

int best_sector_key_shift(const Eigen::VectorXf& q, const Eigen::VectorXf& c) {
  const int n = static_cast<int>(q.size());
  int best = 0;
  double best_error = std::numeric_limits<double>::infinity();
  for (int s = 0; s < n; ++s) {
    double e = 0.0;
    for (int j = 0; j < n; ++j) {
      const double d = q[j] - c[(j + s) % n];
      e += d * d;
    }
    if (e < best_error) {
      best_error = e;
      best = s;
    }
  }
  return best;
}

}  // namespace

ScanContextMatch compare_scan_contexts(const ScanContext& query, const ScanContext& candidate,
                                       const ScanContextConfig& config) {
  const int n = config.sectors;
  const int centre = best_sector_key_shift(query.sector_key, candidate.sector_key);
  const int radius = static_cast<int>(std::round(config.search_ratio * n));
  ScanContextMatch best;
  best.distance = std::numeric_limits<double>::infinity();
  for (int d = -radius; d <= radius; ++d) {
    const int shift = ((centre + d) % n + n) % n;
    const double dist = shifted_distance(query.descriptor, candidate.descriptor, shift);
    if (dist < best.distance) {
      best.distance = dist;
      best.shift = shift;
    }
  }
  // Query sector j shows what the candidate sees in sector j + shift: the query frame is turned by
  // +shift sectors about z in the candidate's frame.
  best.yaw = std::remainder(best.shift * 2.0 * std::numbers::pi / n, 2.0 * std::numbers::pi);
  return best;
}

// The k-d tree over the ring keys (types nested here, not in an unnamed namespace: the class is
// declared in the header, and a member of unnamed-namespace type would be a different type in
// every translation unit that could include this file, as a unity build does).
struct ScanContextDatabase::Tree {
  struct RingKeyCloud {
    const std::vector<float>* keys = nullptr;
    std::size_t dim = 0, count = 0;
    std::size_t kdtree_get_point_count() const { return count; }
    float kdtree_get_pt(std::size_t idx, std::size_t d) const { return (*keys)[idx * dim + d]; }
    template <class Box>
    bool kdtree_get_bbox(Box&) const {
      return false;
    }
  };
  using RingKeyTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, RingKeyCloud>,
                                                          RingKeyCloud, -1, std::size_t>;
  RingKeyCloud cloud;
  RingKeyTree index;
  Tree(const std::vector<float>& keys, std::size_t dim, std::size_t count)
      : cloud{&keys, dim, count}, index(static_cast<int>(dim), cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}  // builds the index
};

ScanContextDatabase::ScanContextDatabase(ScanContextConfig config) : config_(config) { config_.validate(); }
ScanContextDatabase::~ScanContextDatabase() = default;
ScanContextDatabase::ScanContextDatabase(ScanContextDatabase&&) noexcept = default;
ScanContextDatabase& ScanContextDatabase::operator=(ScanContextDatabase&&) noexcept = default;

std::size_t ScanContextDatabase::add(ScanContext context) {
  if (context.ring_key.size() != config_.rings || context.descriptor.cols() != config_.sectors)
    throw Error("ScanContext database: descriptor size does not match the database's configuration");
  ring_keys_.insert(ring_keys_.end(), context.ring_key.data(), context.ring_key.data() + context.ring_key.size());
  contexts_.push_back(std::move(context));
  tree_.reset();  // ring_keys_ may have moved
  return contexts_.size() - 1;
}

std::vector<ScanContextDatabase::Candidate> ScanContextDatabase::query(const ScanContext& q, std::size_t eligible_end,
                                                                       std::size_t neighbours,
                                                                       double max_distance) const {
  eligible_end = std::min(eligible_end, contexts_.size());
  if (eligible_end == 0 || neighbours == 0) return {};
  const std::size_t dim = static_cast<std::size_t>(config_.rings);
  if (!tree_ || tree_->cloud.count != eligible_end) tree_ = std::make_unique<Tree>(ring_keys_, dim, eligible_end);
  const std::size_t k = std::min(neighbours, eligible_end);
  std::vector<std::size_t> indices(k);
  std::vector<float> distances(k);
  nanoflann::KNNResultSet<float, std::size_t> result(k);
  result.init(indices.data(), distances.data());
  tree_->index.findNeighbors(result, q.ring_key.data(), nanoflann::SearchParams());
  std::vector<Candidate> out;
  for (std::size_t i = 0; i < result.size(); ++i) {
    const ScanContextMatch m = compare_scan_contexts(q, contexts_[indices[i]], config_);
    if (m.distance <= max_distance) out.push_back({indices[i], m});
  }
  std::sort(out.begin(), out.end(), [](const Candidate& a, const Candidate& b) {
    return a.match.distance < b.match.distance || (a.match.distance == b.match.distance && a.index < b.index);
  });
  return out;
}

}  // namespace slamvdb::localization
