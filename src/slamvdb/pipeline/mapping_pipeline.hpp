#pragma once
// Replays a recorded sequence through the streaming Mapper: scans, images and poses are given to
// it in time order, from the sequence's ground truth or another pose source, except that a pose
// is given early when a scan or image needs it (the replay knows the whole trajectory, so the
// mapper never waits for a pose, whatever part of the data the trajectory covers).
#include <functional>
#include <string>
#include <vector>

#include "slamvdb/io/dataset.hpp"
#include "slamvdb/pipeline/mapper.hpp"
#include "slamvdb/pipeline/scan_deskew.hpp"
#include "slamvdb/sensors/sensor_input.hpp"

namespace slamvdb {

struct PipelineOptions {
  MapParams map;
  FusionParams fusion;
  std::size_t queue_capacity = 16;                   // items (MapperOptions::max_queued_items)
  std::size_t queue_bytes = std::size_t{1} << 30;    // bytes (MapperOptions::max_queued_bytes)
  QueuePolicy policy = QueuePolicy::kReplay;
  // Give every frame at its time stamp on the wall clock (sensor rate) instead of as fast as the
  // mapper takes it; frames that find the queue full are then dropped and counted.
  bool realtime = false;
  std::size_t max_scans = 0;  // 0: all
  // Scans with per-point times are deskewed before fusion (scan_deskew.hpp): with the poses'
  // motion here, with the odometry's in slam (which deskews when its odometry does).
  bool deskew = true;
  // With deskew: the odometry's motion per scan stamp instead of the poses' (`map --odometry`,
  // whose poses refer to mid-sweep); scans without one are fused as read.
  const SweepMotions* sweeps = nullptr;
  // T_world_lidar (e.g. a pose file); null: the sequence's ground truth.
  const Trajectory* poses = nullptr;
  SubmapStore* store = nullptr;  // where finished submaps go as they finish (may be null)
  double unload_radius = 0;      // MapperOptions::unload_radius
  // Live readers of the map being built (`map|slam --serve`): `map_started` gets the mapper's map
  // once mapping starts (readable while it goes on, through the map's locks) and every submap's
  // info, in memory or not (Mapper::submaps: the anchors of submaps that left memory, which a loop
  // correction moves too); `map_ending` is called before the mapper hands the map out, after which
  // a reader must touch neither. Both may be empty.
  std::function<void(const SemanticMap&, std::function<std::vector<SubmapInfo>()>)> map_started;
  std::function<void()> map_ending;
  // Called once on the replay thread when the first submap is finished (the mapper has taken
  // everything given so far, so the map holds it and the next one has begun), before the next
  // frame is given; mapping goes on when it returns (`map --serve-wait-viewer` holds it there until
  // a viewer follows the map). With `realtime` the replay's clock stops meanwhile. May be empty;
  // the map is the same with or without it.
  std::function<void()> first_submap_finished;
};

// Tells PipelineOptions' live readers (map_started, map_ending) when the mapper's map may be read:
// from construction until end() or destruction (an error that ends mapping early), whichever comes
// first; both come before the map leaves the mapper (Mapper::finish) or the mapper is destroyed.
class LiveReaders {
 public:
  LiveReaders(const Mapper& mapper, const PipelineOptions& options);
  ~LiveReaders() { end(); }
  LiveReaders(const LiveReaders&) = delete;
  LiveReaders& operator=(const LiveReaders&) = delete;
  void end();

 private:
  std::function<void()> ending_;
};

// What a map of `sequence` built with `features` (may be null) and `options` records about itself
// (map_info_for in fusion/projective_fusion.hpp): build_map, slam and the map command use it.
MapInfo map_info_for(const Sequence& sequence, const FeatureSource* features, const PipelineOptions& options);

// The Mapper's options for replaying `sequence` (its camera and calibration) with `options`.
MapperOptions mapper_options(const Sequence& sequence, const PipelineOptions& options);

using ProgressFn = std::function<void(std::size_t done, std::size_t total)>;
// After every scan: scans done, scans in the input (0: not known before reading), and how far the
// stream has read (a recording's bytes and messages).
using StreamProgressFn = std::function<void(std::size_t done, std::size_t total, const StreamProgress& read)>;

// features may be null: geometry only. Throws Error on a configuration problem that would make
// every frame fail (e.g. features of the wrong dimension); single unreadable files are skipped
// and listed in the report.
SemanticMap build_map(const Sequence& sequence, FeatureSource* features, const PipelineOptions& options,
                      PipelineReport& report, const ProgressFn& progress = {});
// Continues `start` (a map a killed run left, loaded back): what it holds up to the end of its
// last submap is skipped, the rest mapped as build_map would.
SemanticMap continue_map(SemanticMap start, const Sequence& sequence, FeatureSource* features,
                         const PipelineOptions& options, PipelineReport& report, const ProgressFn& progress = {});
// The same on any input (a dataset folder or a recording), streamed: the mapping commands' path.
SemanticMap continue_map(SemanticMap start, const SensorInput& input, FeatureSource* features,
                         const PipelineOptions& options, PipelineReport& report, const StreamProgressFn& progress = {});

}  // namespace slamvdb
