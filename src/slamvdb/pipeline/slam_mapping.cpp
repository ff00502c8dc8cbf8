#include "slamvdb/pipeline/slam_mapping.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <deque>
#include <optional>
#include <limits>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/scan_source.hpp"
#include "slamvdb/pipeline/pose_source.hpp"
#include "slamvdb/pipeline/realtime_pacer.hpp"
#include "slamvdb/pipeline/scan_deskew.hpp"

namespace slamvdb {

std::vector<Pose> SlamMappingResult::odometry_poses() const {
  std::vector<Pose> poses;
  for (const Pose& T : tracked.T_odom_sensor) poses.push_back(T_world_odom * T);
  return poses;
}

std::vector<Pose> SlamMappingResult::corrected_poses() const {
  std::vector<Pose> poses;
  for (std::size_t i = 0; i < tracked.stamps.size(); ++i) poses.push_back(T_world_odom * tracked.corrected(i));
  return poses;
}

SlamMappingResult map_with_own_poses(const Sequence& seq, FeatureSource* features, const SlamMappingOptions& options,
                                     const SlamProgress& progress) {
  return map_with_own_poses(*sequence_input(seq), features, options,
                            [&](std::size_t done, std::size_t total, const TrackingResult& r, const StreamProgress&) {
                              if (progress) progress(done, total, r);
                            });
}

SlamMappingResult map_with_own_poses(const SensorInput& input, FeatureSource* features, const SlamMappingOptions& options,
                                     const SlamStreamProgress& progress) {
  const auto t_start = std::chrono::steady_clock::now();
  const Sequence& seq = input.sequence();
  LidarTracker tracker(options.tracking);
  const std::size_t max_scans = options.pipeline.max_scans;
  const std::size_t num_scans = max_scans && input.scan_count() ? std::min(max_scans, input.scan_count())
                                                                 : input.scan_count();
  const auto stream = input.open(features != nullptr);
  // --realtime: each scan is taken when its stamp is due on the wall clock. One that a newer scan
  // overtook while the odometry worked on an earlier one is skipped, as a driver's queue of one
  // would (the odometry goes on with the newest), and counted. To see what has arrived, frames are
  // read ahead into `ahead`: at most what comes in during one scan's registration.
  std::optional<RealtimePacer> pacer;
  std::deque<SensorFrame> ahead;
  bool stream_ended = false;
  const auto next_frame = [&](SensorFrame& out) {
    if (!ahead.empty()) {
      out = std::move(ahead.front());
      ahead.pop_front();
      return true;
    }
    if (!stream_ended && stream->next(out)) return true;
    stream_ended = true;
    return false;
  };
  const auto newer_scan_arrived = [&] {
    for (const SensorFrame& f : ahead)
      if (f.kind == SensorFrame::Kind::kScan && pacer->arrived(f.stamp)) return true;
    while (!stream_ended && (ahead.empty() || pacer->arrived(ahead.back().stamp))) {
      ahead.emplace_back();
      if (!stream->next(ahead.back())) {
        ahead.pop_back();
        stream_ended = true;
        break;
      }
      if (ahead.back().kind == SensorFrame::Kind::kScan && pacer->arrived(ahead.back().stamp)) return true;
    }
    return false;
  };
  SensorFrame frame;
  bool have = next_frame(frame);
  if (options.pipeline.realtime && have) pacer.emplace(frame.stamp);
  double last_frame_stamp = have ? frame.stamp : 0.0;
  // T_world_odom (odometry_start_pose at the first scan), set when the first scan comes.
  Pose G = Pose::Identity(), G_inv = Pose::Identity();
  // The loop closer's correction C (odometry frame) as the map's world sees it: G C G^-1.
  const auto world_correction = [&](double stamp) {
    return G * tracker.result().loop_closer->correction_at(stamp) * G_inv;
  };

  const MapInfo info = map_info_for(seq, features, options.pipeline);
  Mapper mapper(mapper_options(seq, options.pipeline), SemanticMap(options.pipeline.map, info), features,
                options.pipeline.store);
  LiveReaders live(mapper, options.pipeline);
  SubmapCorrections corrections;
  Pose K_given = Pose::Identity();  // the correction in the poses given to the mapper
  std::size_t loops_seen = 0, optimizations_seen = 0;
  double last_pose_stamp = -std::numeric_limits<double>::infinity();
  std::optional<Pose> last_odometry;  // G T_odom_sensor of the last pose given

  // Images are given once the pose after them is (the next readable scan's, or the end of the
  // poses): given before it, they would wait in the mapper's queue for a pose only this thread
  // can give, and a run of unreadable scans would fill the queue and stop this thread for good.
  // They wait here meanwhile (the images between two scans).
  std::size_t si = 0, unreadable = 0, with_times = 0, deskewed = 0, overtaken = 0;
  double last_scan_stamp = -std::numeric_limits<double>::infinity();
  std::deque<ImageRecord> images;
  const auto give_images_before = [&](double stamp) {
    while (!images.empty() && images.front().stamp < stamp) {
      mapper.add_image(images.front());
      images.pop_front();
    }
  };
  for (; have; have = next_frame(frame)) {
    if (frame.kind == SensorFrame::Kind::kImage) {
      // With --max-scans, the images up to the last mapped scan's stamp.
      if (max_scans && si == max_scans && frame.stamp > last_scan_stamp) break;
      images.push_back(std::move(frame.image));
      continue;
    }
    if (max_scans && si == max_scans) break;
    if (si++ == 0) {
      G = odometry_start_pose(seq, frame.stamp);
      G_inv = G.inverse();
    }
    last_scan_stamp = frame.stamp;
    if (pacer) {
      pacer->wait_for(frame.stamp);
      last_frame_stamp = frame.stamp;
      if (newer_scan_arrived()) {
        ++overtaken;
        if (progress) progress(si, num_scans, tracker.result(), stream->progress());
        continue;
      }
    }
    if (!frame.error.empty()) {
      mapper.add_unreadable_scan(frame.error);
      ++unreadable;
      if (progress) progress(si, num_scans, tracker.result(), stream->progress());
      continue;
    }
    const ScanRecord rec{frame.stamp, frame.name, {}};
    ScanPoints scan{std::move(frame.points), std::move(frame.point_times)};
    const Pose T_odom_sensor =
        tracker.track(rec.stamp, scan.points, scan.time.empty() ? nullptr : &scan.time, rec.points.string());
    if (!scan.time.empty()) {
      ++with_times;
      // The whole scan deskewed with the motion the odometry deskewed its own points with, into
      // the mid-sweep frame its pose refers to.
      if (options.pipeline.deskew && tracker.last_sweep()) {
        deskew_with_sweep(*tracker.last_sweep(), scan.points, scan.time);
        ++deskewed;
      }
    }
    const auto* closer = tracker.result().loop_closer.get();
    if (closer && (closer->optimizations() != optimizations_seen || closer->loops().size() != loops_seen)) {
      // The pose graph changed: move every submap to the new correction once the mapper holds
      // every scan given so far, and give later poses with it. The last pose is given again just
      // after its stamp, corrected, so that images between it and this scan are placed in the
      // corrected world too.
      mapper.wait_until_idle();
      mapper.correct_submaps(corrections.move(mapper.submaps(), world_correction));
      for (std::size_t l = loops_seen; l < closer->loops().size(); ++l)
        corrections.add_loop(closer->loops()[l].candidate_stamp, closer->loops()[l].query_stamp);
      loops_seen = closer->loops().size(), optimizations_seen = closer->optimizations();
      K_given = world_correction(rec.stamp);
      if (last_odometry) {
        const double just_after = std::nextafter(last_pose_stamp, std::numeric_limits<double>::infinity());
        if (just_after < rec.stamp) {
          mapper.add_pose(just_after, K_given * *last_odometry);
          corrections.poses_given_with(just_after, K_given);
        }
      } else {
        corrections.poses_given_with(rec.stamp, K_given);
      }
    }
    last_odometry = G * T_odom_sensor;
    last_pose_stamp = rec.stamp;
    mapper.add_pose(rec.stamp, K_given * *last_odometry);
    give_images_before(rec.stamp);  // a scan before an image of the same stamp
    mapper.add_scan(rec.stamp, std::move(scan.points));
    if (corrections.pending_loops())
      corrections.merge_ready(mapper.submaps(), mapper.map().active_submap_id(),
                              [&](int target, int source) { return mapper.merge_submaps(target, source, options.merge); });
    if (progress) progress(si, num_scans, tracker.result(), stream->progress());
    if (mapper.failed()) break;  // finish() names the error
  }
  if (!mapper.failed()) tracker.require_registered(seq.root.string(), unreadable);
  mapper.end_poses();
  // After the last pose (counted), the images up to the last scan (later ones are not part of the run).
  if (!mapper.failed()) give_images_before(std::nextafter(last_scan_stamp, std::numeric_limits<double>::infinity()));
  mapper.end_mapping();
  // Loops whose newest submap was still being written: it is finished now (merged through the
  // mapper, which reads submaps back from the store and keeps the store in step).
  corrections.merge_ready(mapper.submaps(), std::nullopt, [&](int target, int source) {
    return mapper.merge_submaps(target, source, options.merge);
  });
  live.end();
  SemanticMap map = mapper.finish();
  PipelineReport report = mapper.report();
  report.input_skipped = stream->skipped();
  report.scans_with_point_times = with_times;
  report.scans_deskewed = deskewed;
  if (options.pipeline.deskew && options.tracking.odometry.deskew)
    report.deskew_motion = kOdometryDeskewMotion;
  report.seconds_total = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  if (pacer) {
    report.scans_overtaken = overtaken;
    report.realtime_seconds_behind = std::max(0.0, pacer->elapsed() - (last_frame_stamp - pacer->first_stamp()));
  }
  return SlamMappingResult{std::move(map), std::move(report), tracker.take_result(), corrections.report(), G};
}

}  // namespace slamvdb
