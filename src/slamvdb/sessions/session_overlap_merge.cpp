#include "slamvdb/sessions/session_overlap_merge.hpp"

#include <Eigen/Geometry>
#include <tbb/parallel_for.h>

#include "slamvdb/map/submap_merge.hpp"

namespace slamvdb::sessions {
namespace {

// The world box around a submap's occupied voxels (their centres, grown by a voxel): two submaps
// whose boxes are apart cannot overlap, so most pairs of a long drive cost one box test.
Eigen::AlignedBox3d overlap_merge_world_box(const SubmapInfo& info, const VoxelMap& voxels) {
  Eigen::AlignedBox3d box;
  const double voxel = voxels.voxel_size();
  voxels.occupancy().for_each_occupied(
      [&](const VoxelKey& k, float) { box.extend(info.T_world_submap * center_of_key(k, voxel)); });
  if (!box.isEmpty()) box.min().array() -= voxel, box.max().array() += voxel;
  return box;
}

uint64_t overlap_merge_observations(const VoxelMap& voxels) {
  uint64_t n = 0;
  const SemanticLayer& layer = voxels.semantics();
  layer.for_each([&](SemanticLayer::Handle h) { n += layer.count_of(h); });
  return n;
}

}  // namespace

std::vector<SubmapAbsorption> merge_overlapping_sessions(std::vector<std::pair<SubmapInfo, VoxelMap>>& submaps,
                                                         const OverlapMergeOptions& options,
                                                         const SessionOrder& sessions) {
  std::vector<SubmapAbsorption> out;
  if (!options.enabled) return out;
  std::vector<Eigen::AlignedBox3d> boxes(submaps.size());
  tbb::parallel_for(std::size_t{0}, submaps.size(),
                    [&](std::size_t i) { boxes[i] = overlap_merge_world_box(submaps[i].first, submaps[i].second); });
  std::vector<bool> absorbed(submaps.size(), false);
  for (std::size_t s = 0; s < submaps.size(); ++s) {
    // Named references, not a structured binding: the lambda below captures them (clang 14 refuses
    // to capture a structured binding).
    const SubmapInfo& source_info = submaps[s].first;
    const VoxelMap& source = submaps[s].second;
    std::vector<std::size_t> candidates;
    for (std::size_t t = 0; t < s; ++t) {
      const SubmapInfo& target_info = submaps[t].first;
      if (!absorbed[t] && target_info.session != source_info.session && boxes[t].intersects(boxes[s]))
        candidates.push_back(t);
    }
    // The candidates' overlaps are independent reads (a third of a 3 km merge): in parallel, the
    // choice then made in candidate order as before, so the result does not depend on the threads.
    std::vector<double> overlaps(candidates.size());
    tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t c) {
      const auto& [target_info, target] = submaps[candidates[c]];
      overlaps[c] = occupied_overlap(target, source, target_info.T_world_submap.inverse() * source_info.T_world_submap);
    });
    std::size_t best = s;
    double best_overlap = -1;
    for (std::size_t c = 0; c < candidates.size(); ++c)
      if (overlaps[c] >= options.min_overlap && overlaps[c] > best_overlap) best = candidates[c], best_overlap = overlaps[c];
    if (best == s) continue;
    auto& [target_info, target] = submaps[best];
    SubmapAbsorption a{.target_id = target_info.id,
                       .source_id = source_info.id,
                       .target_session = target_info.session,
                       .source_session = source_info.session,
                       .overlap = best_overlap,
                       .observations_moved = overlap_merge_observations(source)};
    const auto occupied_before =
        static_cast<int64_t>(target.occupancy().num_occupied_voxels() + source.occupancy().num_occupied_voxels());
    const MergeReport r = merge_into(target, source, target_info.T_world_submap.inverse() * source_info.T_world_submap, sessions);
    a.observations_dropped_free = r.counts_dropped_free;
    a.observations_clipped = r.counts_before - r.counts_after - r.counts_dropped_free;
    a.semantic_voxels_removed = r.semantic_entries_before - r.semantic_entries_after;
    a.occupied_voxels_removed = occupied_before - static_cast<int64_t>(target.occupancy().num_occupied_voxels());
    boxes[best].extend(boxes[s]);
    absorbed[s] = true;
    out.push_back(a);
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < submaps.size(); ++i)
    if (!absorbed[i] && kept++ != i) submaps[kept - 1] = std::move(submaps[i]);  // never onto itself
  submaps.erase(submaps.begin() + static_cast<std::ptrdiff_t>(kept), submaps.end());
  return out;
}

}  // namespace slamvdb::sessions
