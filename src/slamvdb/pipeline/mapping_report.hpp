#pragma once
// What a mapping run did with every scan, image and pose it was given: each one is either used or
// counted under the reason it was not (nothing is dropped silently).
#include <cstddef>
#include <string>
#include <vector>

#include "slamvdb/fusion/projective_fusion.hpp"
#include "slamvdb/map/voxel_map.hpp"

namespace slamvdb {

// What happens to a sensor item that finds the mapper's queue full.
enum class QueuePolicy {
  kDropWhenFull,  // live operation: the item is dropped and counted; the caller never waits
  kReplay,        // replay: the caller waits for room, so no item is lost and the map does not
                  // depend on timing
};

struct InferenceStats {
  std::size_t completed = 0, failed = 0, dropped_queue_full = 0;
  double busy_seconds = 0.0;  // feature extraction on the inference thread
};

struct PipelineReport {
  // Scans: received = integrated + failed + without_pose + out_of_order + duplicate + queue_full
  // + resumed.
  std::size_t scans_total = 0, scans_integrated = 0, scans_failed = 0, scans_without_pose = 0;
  std::size_t scans_out_of_order = 0, scans_duplicate = 0, scans_queue_full = 0, scans_resumed = 0;
  // Images: received = fused + failed + outside_pose_range + before_first_scan + out_of_order
  // + duplicate + inference.dropped_queue_full + resumed.
  std::size_t images_total = 0, images_fused = 0, images_failed = 0, images_outside_pose_range = 0;
  std::size_t images_before_first_scan = 0, images_out_of_order = 0, images_duplicate = 0, images_resumed = 0;
  // Poses: received = used + out_of_order + duplicate + invalid.
  std::size_t poses_total = 0, poses_out_of_order = 0, poses_duplicate = 0, poses_invalid = 0;
  std::size_t submaps = 0;           // submaps in the map at the end (in memory or in the store)
  std::size_t submaps_unloaded = 0;  // times a finished submap left memory for the store
  std::size_t submaps_reloaded = 0;  // times one was read back
  std::size_t peak_submaps_in_memory = 0, submaps_in_memory_at_end = 0;
  std::size_t peak_queued_items = 0, peak_queued_bytes = 0;
  // Deskewing (scan_deskew.hpp): scans read with per-point times, and those deskewed with the
  // motion `deskew_motion` names (empty: deskewing was off).
  std::size_t scans_with_point_times = 0, scans_deskewed = 0;
  std::string deskew_motion;
  ScanIntegrationStats points;
  InferenceStats inference;
  FusionStats fusion;  // summed over images
  double seconds_scans = 0, seconds_fusion = 0, seconds_total = 0;
  // Real-time replay only: how long after the last frame's time the mapper had done all (< 0: not
  // a real-time run).
  double realtime_seconds_behind = -1;
  // Real-time slam only: scans never given to the mapper because a newer scan had arrived while
  // the odometry worked on an earlier one (not in scans_total).
  std::size_t scans_overtaken = 0;
  // One line per item not used, with the reason (the first kMaxProblems; the counts above are complete).
  static constexpr std::size_t kMaxProblems = 1000;
  std::vector<std::string> problems;
  std::size_t problems_not_listed = 0;
  // What the input skipped and counted (a recording's messages of unknown types, or that do not
  // decode with --skip-bad-messages), one line each.
  std::vector<std::string> input_skipped;

  void add_problem(std::string line);
  std::size_t sensor_items_dropped() const;
  std::string summary() const;
  std::string deskew_summary() const;  // one line, also in summary()
};

}  // namespace slamvdb
