#include "slamvdb/pipeline/mapping_pipeline.hpp"

#include <fmt/format.h>

#include <chrono>
#include <thread>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/scan_io.hpp"

namespace slamvdb {

namespace {
using Clock = std::chrono::steady_clock;
}  // namespace

MapInfo map_info_for(const Sequence& seq, const FeatureSource* features, const PipelineOptions& options) {
  return map_info_for(seq.root.string(), features ? features->model_id() : "", features ? features->description() : "",
                      options.fusion);
}

MapperOptions mapper_options(const Sequence& seq, const PipelineOptions& options) {
  MapperOptions m;
  m.map = options.map;
  m.fusion = options.fusion;
  m.camera = seq.camera;
  m.T_lidar_camera = seq.T_lidar_camera;
  m.policy = options.realtime ? QueuePolicy::kDropWhenFull : options.policy;
  m.max_queued_items = options.queue_capacity;
  m.max_queued_bytes = options.queue_bytes;
  m.unload_radius = options.unload_radius;
  return m;
}

SemanticMap build_map(const Sequence& seq, FeatureSource* features, const PipelineOptions& options,
                      PipelineReport& report, const ProgressFn& progress) {
  return continue_map(SemanticMap(options.map, map_info_for(seq, features, options)), seq, features, options, report,
                      progress);
}

SemanticMap continue_map(SemanticMap start, const Sequence& seq, FeatureSource* features,
                         const PipelineOptions& options, PipelineReport& report, const ProgressFn& progress) {
  const auto t_start = Clock::now();
  const Trajectory& poses = options.poses ? *options.poses : seq.poses;
  if (poses.empty())
    throw Error(fmt::format("sequence {} has no poses (poses.txt) and no other pose source was given; mapping needs "
                            "a pose for every scan", seq.root.string()));
  const std::size_t num_scans =
      options.max_scans ? std::min(options.max_scans, seq.scans.size()) : seq.scans.size();
  // With --max-scans, the images after the last mapped scan are not part of the run.
  std::size_t num_images = features ? seq.images.size() : 0;
  if (options.max_scans) {
    const double last_stamp = num_scans ? seq.scans[num_scans - 1].stamp : -1e300;
    num_images = 0;
    while (features && num_images < seq.images.size() && seq.images[num_images].stamp <= last_stamp) ++num_images;
  }

  Mapper mapper(mapper_options(seq, options), std::move(start), features, options.store);
  // The three streams in time order; at equal stamps a pose first (it covers the data of its
  // time), then the scan, then the image. The whole trajectory is known, so before each scan or
  // image every pose up to the first one at or after its stamp is given (earlier than its own
  // time if need be): the mapper never waits for a pose this thread holds back, which with a full
  // queue would wait for ever (a trajectory starting after the data, or with a gap longer than the
  // queue). The end of the poses is announced with the last one.
  std::size_t pi = 0, si = 0, ii = 0;
  const auto give_pose = [&] {
    mapper.add_pose(poses.stamps()[pi], poses.poses()[pi]);
    if (++pi == poses.size()) mapper.end_poses();  // what comes after the last pose needs no wait
  };
  const auto give_poses_covering = [&](double stamp) {
    while (pi < poses.size() && (pi == 0 || poses.stamps()[pi - 1] < stamp)) give_pose();
  };
  const double t0 = std::min(num_scans ? seq.scans[0].stamp : 1e300, num_images ? seq.images[0].stamp : 1e300);
  double last_frame = t0;
  while (si < num_scans || ii < num_images) {
    const double tp = pi < poses.size() ? poses.stamps()[pi] : 1e300;
    const double ts = si < num_scans ? seq.scans[si].stamp : 1e300;
    const double ti = ii < num_images ? seq.images[ii].stamp : 1e300;
    const double t = std::min({tp, ts, ti});
    if (options.realtime) {
      std::this_thread::sleep_until(t_start + std::chrono::duration_cast<Clock::duration>(
                                                  std::chrono::duration<double>(t - t0)));
      last_frame = t;
    }
    if (tp == t) {
      give_pose();
    } else if (ts == t) {
      const ScanRecord& rec = seq.scans[si++];
      give_poses_covering(rec.stamp);
      try {
        mapper.add_scan(rec.stamp, read_scan(rec).points);
      } catch (const Error& e) {
        mapper.add_unreadable_scan(fmt::format("scan {}: {}", rec.points.filename().string(), e.what()));
      }
      if (progress) progress(si, num_scans);
    } else {
      give_poses_covering(ti);
      mapper.add_image(seq.images[ii++]);
    }
    if (mapper.failed()) break;  // finish() names the error
  }
  while (pi < poses.size()) give_pose();  // no data left to wait for them (--realtime ends with the data)
  SemanticMap map = mapper.finish();
  report = mapper.report();
  report.seconds_total = std::chrono::duration<double>(Clock::now() - t_start).count();
  if (options.realtime) report.realtime_seconds_behind = std::max(0.0, report.seconds_total - (last_frame - t0));
  return map;
}

}  // namespace slamvdb
