#pragma once
// Replays a sequence into a semantic map: scans -> occupancy, images -> features -> fusion, with
// the poses the sequence provides (ground truth; a tracker can stand in later).
#include <functional>
#include <string>
#include <vector>

#include "slamvdb/fusion/projective_fusion.hpp"
#include "slamvdb/io/dataset.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/pipeline/inference_worker.hpp"

namespace slamvdb {

struct PipelineOptions {
  MapParams map;
  FusionParams fusion;
  std::size_t queue_capacity = 4;
  QueuePolicy policy = QueuePolicy::kReplay;
  std::size_t max_scans = 0;  // 0: all
};

struct PipelineReport {
  std::size_t scans_total = 0, scans_integrated = 0, scans_failed = 0, scans_without_pose = 0;
  std::size_t images_total = 0, images_fused = 0, images_failed = 0, images_outside_pose_range = 0;
  std::size_t images_before_first_scan = 0;
  std::size_t submaps = 0;
  ScanIntegrationStats points;
  InferenceStats inference;
  FusionStats fusion;  // summed over images
  double seconds_scans = 0, seconds_fusion = 0, seconds_total = 0;
  std::vector<std::string> problems;  // one line per skipped scan or image, with the reason

  std::string summary() const;
};

using ProgressFn = std::function<void(std::size_t done, std::size_t total)>;

// features may be null: geometry only. Throws Error on a configuration problem that would make
// every frame fail (e.g. features of the wrong dimension); single unreadable files are skipped
// and listed in the report.
SemanticMap build_map(const Sequence& sequence, FeatureSource* features, const PipelineOptions& options,
                      PipelineReport& report, const ProgressFn& progress = {});

}  // namespace slamvdb
