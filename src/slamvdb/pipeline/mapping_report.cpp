#include "slamvdb/pipeline/mapping_report.hpp"

#include <fmt/format.h>

namespace slamvdb {

void PipelineReport::add_problem(std::string line) {
  if (problems.size() < kMaxProblems) problems.push_back(std::move(line));
  else ++problems_not_listed;
}

std::size_t PipelineReport::sensor_items_dropped() const {
  return scans_failed + scans_without_pose + scans_out_of_order + scans_duplicate + scans_queue_full + images_failed +
         images_outside_pose_range + images_before_first_scan + images_out_of_order + images_duplicate +
         inference.dropped_queue_full;
}

std::string PipelineReport::deskew_summary() const {
  if (scans_with_point_times == 0) return "deskewing: no scan has per-point times (scans fused as read)";
  if (deskew_motion.empty())
    return fmt::format("deskewing: off; {} scans with per-point times fused as read", scans_with_point_times);
  return fmt::format("deskewing: {} of {} scans with per-point times deskewed, motion from {}{}", scans_deskewed,
                     scans_with_point_times, deskew_motion,
                     scans_deskewed < scans_with_point_times ? " (the others fused as read)" : "");
}

std::string PipelineReport::summary() const {
  std::string s = fmt::format(
      "scans: {} integrated of {} ({} unreadable, {} outside the pose range, {} out of order, {} duplicate stamps, "
      "{} dropped on a full queue{})\n"
      "points: {} ({} dropped: {} NaN/Inf, {} no return, {} too close, {} outside the map extent; {} beyond max "
      "range, cleared only)\n"
      "images: {} fused of {} ({} failed, {} outside the pose range, {} before the first scan, {} out of order, {} "
      "duplicate stamps, {} dropped on a full queue{})\n"
      "poses: {} received ({} out of order, {} duplicate stamps, {} not a finite rigid transform)\n"
      "fusion: {} voxel updates, {} occluded candidates, {:.1f}% of pixels on a voxel; skipped feature pixels: {} "
      "non-finite, {} all-zero; {} frames refused as mostly invalid\n"
      "submaps: {}{}\n"
      "queue: peak {} items, {:.0f} MB\n"
      "time: {:.1f} s total, {:.1f} s scans, {:.1f} s fusion, {:.1f} s feature extraction (inference thread)",
      scans_integrated, scans_total, scans_failed, scans_without_pose, scans_out_of_order, scans_duplicate,
      scans_queue_full, scans_resumed ? fmt::format(", {} already in the resumed map", scans_resumed) : "",
      points.points, points.dropped(), points.dropped_nonfinite, points.dropped_no_return, points.dropped_too_close,
      points.dropped_out_of_extent, points.beyond_max_range, images_fused, images_total, images_failed,
      images_outside_pose_range, images_before_first_scan, images_out_of_order, images_duplicate,
      inference.dropped_queue_full,
      images_resumed ? fmt::format(", {} already in the resumed map", images_resumed) : "", poses_total,
      poses_out_of_order, poses_duplicate, poses_invalid, fusion.fused_voxels, fusion.occluded,
      fusion.pixels_total ? 100.0 * fusion.pixels_used / fusion.pixels_total : 0.0, fusion.pixels_nonfinite,
      fusion.pixels_zero, fusion.frames_refused_invalid, submaps,
      submaps_unloaded ? fmt::format(", at most {} in memory at once, {} at the end ({} times one left memory for the "
                                     "map file, {} times one was read back)",
                                     peak_submaps_in_memory, submaps_in_memory_at_end, submaps_unloaded,
                                     submaps_reloaded)
                       : fmt::format(", at most {} in memory at once", peak_submaps_in_memory),
      peak_queued_items, peak_queued_bytes / 1e6, seconds_total, seconds_scans, seconds_fusion,
      inference.busy_seconds);
  s += '\n';
  s += deskew_summary();
  if (realtime_seconds_behind >= 0)
    s += fmt::format("\nreal time: kept up with {} of {} scans{} and {} of {} images; done {:.2f} s after the last frame",
                     scans_integrated, scans_total + scans_overtaken,
                     scans_overtaken ? fmt::format(" ({} overtaken by a newer scan while the odometry worked)",
                                                   scans_overtaken)
                                     : "",
                     images_fused, images_total, realtime_seconds_behind);
  for (const std::string& line : input_skipped) s += "\ninput: " + line;
  for (std::size_t i = 0; i < problems.size() && i < 20; ++i) s += "\n  skipped: " + problems[i];
  if (problems.size() + problems_not_listed > 20)
    s += fmt::format("\n  ... and {} more", problems.size() + problems_not_listed - 20);
  return s;
}

}  // namespace slamvdb
