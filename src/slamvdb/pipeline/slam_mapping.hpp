#pragma once
// Mapping on the project's own poses, streamed (paper Figure 6.1): each scan is registered by the
// LiDAR odometry and its pose given to the Mapper at once, with the scan and the images around
// it; when the loop-closing mapper accepts a loop, the Mapper's submaps are moved to the corrected
// trajectory (Mapper::correct_submaps) while mapping goes on, later poses are given corrected, and
// submaps the loop shows to be the same place are merged once both are finished.
#include <functional>

#include "slamvdb/io/dataset.hpp"
#include "slamvdb/pipeline/lidar_tracking.hpp"
#include "slamvdb/pipeline/loop_corrections.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"

namespace slamvdb {

struct SlamMappingOptions {
  // poses are not used; store and unload_radius as in map; deskew: the map fuses the scans deskewed
  // as the odometry deskews them (so only when tracking.odometry.deskew too); realtime: scans are
  // taken at their stamps, and one a newer scan overtook while the odometry was busy is skipped
  // (PipelineReport::scans_overtaken)
  PipelineOptions pipeline;
  TrackingOptions tracking;
  MergeOptions merge;
};

struct SlamMappingResult {
  SemanticMap map;
  PipelineReport report;
  TrackingResult tracked;
  LoopCorrectionReport corrections;
  Pose T_world_odom = Pose::Identity();  // odometry_start_pose (pose_source.hpp)
  std::vector<Pose> odometry_poses() const;  // T_world_sensor per tracked scan, odometry only
  std::vector<Pose> corrected_poses() const;  // the same after the final loop corrections
};

// progress(done, total, tracking so far) after every scan. Throws Error when the odometry is lost,
// no scan could be registered, or the mapper fails; unreadable scans are skipped and counted.
using SlamProgress = std::function<void(std::size_t, std::size_t, const TrackingResult&)>;
SlamMappingResult map_with_own_poses(const Sequence& sequence, FeatureSource* features,
                                     const SlamMappingOptions& options, const SlamProgress& progress = {});
// The same on any input (a dataset folder or a recording), streamed; progress also gets how far
// the stream has read.
using SlamStreamProgress = std::function<void(std::size_t, std::size_t, const TrackingResult&, const StreamProgress&)>;
SlamMappingResult map_with_own_poses(const SensorInput& input, FeatureSource* features,
                                     const SlamMappingOptions& options, const SlamStreamProgress& progress = {});

}  // namespace slamvdb
