#include "slamvdb/pipeline/mapping_pipeline.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <utility>

#include "slamvdb/core/error.hpp"
#include "slamvdb/pipeline/realtime_pacer.hpp"
#include "slamvdb/pipeline/scan_deskew.hpp"

namespace slamvdb {

namespace {
using Clock = std::chrono::steady_clock;

// Whether the map has a finished submap once the mapper has taken everything given so far (it
// finishes one when a scan leaves its length, so this is known only after that scan is mapped).
bool has_finished_submap(Mapper& mapper) {
  mapper.wait_until_idle();
  const std::vector<SubmapInfo> submaps = mapper.submaps();
  return std::any_of(submaps.begin(), submaps.end(), [](const SubmapInfo& s) { return s.finished; });
}
}  // namespace

MapInfo map_info_for(const Sequence& seq, const FeatureSource* features, const PipelineOptions& options) {
  return map_info_for(seq.root.string(), features ? features->model_id() : "", features ? features->description() : "",
                      options.fusion);
}

LiveReaders::LiveReaders(const Mapper& mapper, const PipelineOptions& options) : ending_(options.map_ending) {
  if (options.map_started) options.map_started(mapper.map(), [&mapper] { return mapper.submaps(); });
}

void LiveReaders::end() {
  if (const auto ending = std::exchange(ending_, nullptr)) ending();
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
  return continue_map(std::move(start), *sequence_input(seq), features, options, report,
                      [&](std::size_t done, std::size_t total, const StreamProgress&) {
                        if (progress) progress(done, options.max_scans ? std::min(options.max_scans, total) : total);
                      });
}

SemanticMap continue_map(SemanticMap start, const SensorInput& input, FeatureSource* features,
                         const PipelineOptions& options, PipelineReport& report, const StreamProgressFn& progress) {
  const auto t_start = Clock::now();
  const Sequence& seq = input.sequence();
  const Trajectory& poses = options.poses ? *options.poses : seq.poses;
  if (poses.empty())
    throw Error(fmt::format("{} has no poses ({}) and no other pose source was given; mapping needs a pose for every "
                            "scan",
                            seq.root.string(), input.is_recording() ? "no pose topic" : "poses.txt"));
  const std::size_t total_scans =
      options.max_scans && input.scan_count() ? std::min(options.max_scans, input.scan_count()) : input.scan_count();
  const auto stream = input.open(features != nullptr);

  Mapper mapper(mapper_options(seq, options), std::move(start), features, options.store);
  LiveReaders live(mapper, options);
  // The streams in time order; at equal stamps a pose first (it covers the data of its time),
  // then the scan, then the image. The whole trajectory is known, so before each scan or image
  // every pose up to the first one at or after its stamp is given (earlier than its own time if
  // need be): the mapper never waits for a pose this thread holds back, which with a full queue
  // would wait for ever (a trajectory starting after the data, or with a gap longer than the
  // queue). The end of the poses is announced with the last one.
  std::size_t pi = 0, scans = 0, with_times = 0, deskewed = 0;
  const auto give_pose = [&] {
    mapper.add_pose(poses.stamps()[pi], poses.poses()[pi]);
    if (++pi == poses.size()) mapper.end_poses();  // what comes after the last pose needs no wait
  };
  const auto give_poses_covering = [&](double stamp) {
    while (pi < poses.size() && (pi == 0 || poses.stamps()[pi - 1] < stamp)) give_pose();
  };
  SensorFrame frame;
  bool have = stream->next(frame);
  const double t0 = have ? frame.stamp : 0.0;
  double last_frame = t0, last_scan = -1e300;
  std::optional<RealtimePacer> pacer;
  if (options.realtime) pacer.emplace(t0);
  std::function<void()> first_submap_finished = options.first_submap_finished;  // called once
  const auto wait_for = [&](double t) {
    if (!pacer) return;
    pacer->wait_for(t);
    last_frame = t;
  };
  while (have) {
    // With --max-scans, the frames after the last mapped scan (images up to its stamp) are not part of the run.
    if (options.max_scans && scans == options.max_scans &&
        (frame.kind == SensorFrame::Kind::kScan || frame.stamp > last_scan))
      break;
    if (pi < poses.size() && poses.stamps()[pi] <= frame.stamp) {
      wait_for(poses.stamps()[pi]);
      give_pose();
      continue;
    }
    wait_for(frame.stamp);
    give_poses_covering(frame.stamp);
    if (frame.kind == SensorFrame::Kind::kScan) {
      if (frame.error.empty()) {
        if (!frame.point_times.empty()) {
          ++with_times;
          if (options.deskew && !options.sweeps) {
            deskewed += deskew_with_trajectory(poses, frame.stamp, frame.points, frame.point_times);
          } else if (options.deskew) {  // the odometry's motion, when it had one for this scan
            if (const auto sweep = options.sweeps->find(frame.stamp); sweep != options.sweeps->end()) {
              deskew_with_sweep(sweep->second, frame.points, frame.point_times);
              ++deskewed;
            }
          }
        }
        mapper.add_scan(frame.stamp, std::move(frame.points));
      } else {
        mapper.add_unreadable_scan(frame.error);
      }
      last_scan = frame.stamp;
      ++scans;
      if (progress) progress(scans, total_scans, stream->progress());
      if (first_submap_finished && has_finished_submap(mapper)) {
        const auto held = Clock::now();
        std::exchange(first_submap_finished, nullptr)();
        if (pacer) pacer->postpone(Clock::now() - held);
      }
    } else {
      mapper.add_image(std::move(frame.image));
    }
    if (mapper.failed()) break;  // finish() names the error
    have = stream->next(frame);
  }
  while (pi < poses.size()) give_pose();  // no data left to wait for them (--realtime ends with the data)
  mapper.end_mapping();  // the last submap finishes while live readers still see the map
  live.end();
  SemanticMap map = mapper.finish();
  report = mapper.report();
  report.input_skipped = stream->skipped();
  report.scans_with_point_times = with_times;
  report.scans_deskewed = deskewed;
  if (options.deskew) report.deskew_motion = options.sweeps ? kOdometryDeskewMotion : kTrajectoryDeskewMotion;
  report.seconds_total = std::chrono::duration<double>(Clock::now() - t_start).count();
  if (pacer) report.realtime_seconds_behind = std::max(0.0, pacer->elapsed() - (last_frame - t0));
  return map;
}

}  // namespace slamvdb
