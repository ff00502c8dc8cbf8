#pragma once
// ScanContext place recognition (Kim & Kim, "Scan Context: Egocentric Spatial Descriptor for
// Place Recognition within 3D Point Cloud Map", IROS 2018), our own implementation: a polar grid
// of rings x sectors around the sensor holding the highest point of each bin, a rotation-invariant
// ring key (mean per ring) searched in a k-d tree (nanoflann), a sector key (mean per sector)
// whose best circular alignment seeds the column-shift search, and the column-wise cosine
// distance minimised over shifts, whose best shift is the yaw between the two scans.
#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb::localization {

struct ScanContextConfig {
  int rings = 20;
  int sectors = 60;
  double max_radius = 80.0;    // metres
  double height_offset = 2.0;  // added to z so the ground under the sensor is above 0 (empty bins are 0)
  double search_ratio = 0.1;   // fraction of the sectors searched around the sector-key alignment
  void validate() const;
};

struct ScanContext {
  Eigen::MatrixXf descriptor;  // rings x sectors: max height per bin, 0 where empty
  Eigen::VectorXf ring_key;    // mean per ring
  Eigen::VectorXf sector_key;  // mean per sector
};

// Points in the sensor frame (z up); non-finite and out-of-radius points are ignored.
ScanContext make_scan_context(const std::vector<Vec3d>& points_sensor, const ScanContextConfig& config);

struct ScanContextMatch {
  double distance = 1.0;  // 0 (identical) .. 1 (nothing in common)
  int shift = 0;          // sectors
  double yaw = 0.0;       // radians: rotation about z of the query's sensor frame in the candidate's
};
ScanContextMatch compare_scan_contexts(const ScanContext& query, const ScanContext& candidate,
                                       const ScanContextConfig& config);

// The descriptors of every keyframe, with a k-d tree over their ring keys.
class ScanContextDatabase {
 public:
  explicit ScanContextDatabase(ScanContextConfig config = {});
  ~ScanContextDatabase();
  ScanContextDatabase(ScanContextDatabase&&) noexcept;
  ScanContextDatabase& operator=(ScanContextDatabase&&) noexcept;

  std::size_t add(ScanContext context);  // returns its index
  std::size_t size() const { return contexts_.size(); }
  const ScanContext& at(std::size_t i) const { return contexts_[i]; }

  struct Candidate {
    std::size_t index = 0;
    ScanContextMatch match;
  };
  // The `ring_key_neighbours` nearest ring keys among entries [0, eligible_end), re-ranked by the
  // full descriptor distance; those under max_distance, best first.
  std::vector<Candidate> query(const ScanContext& query, std::size_t eligible_end, std::size_t ring_key_neighbours,
                               double max_distance) const;
  const ScanContextConfig& config() const { return config_; }

 private:
  struct Tree;
  ScanContextConfig config_;
  std::vector<ScanContext> contexts_;
  std::vector<float> ring_keys_;       // flat, rings floats per entry
  mutable std::unique_ptr<Tree> tree_; // rebuilt lazily when the eligible prefix grows
};

}  // namespace slamvdb::localization
