#include "slamvdb/pipeline/mapping_pipeline.hpp"

#include <fmt/format.h>

#include <chrono>
#include <deque>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/scan_io.hpp"

namespace slamvdb {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

void add(FusionStats& a, const FusionStats& b) {
  a.candidates += b.candidates, a.fused_voxels += b.fused_voxels, a.occluded += b.occluded;
  a.pixels_used += b.pixels_used, a.pixels_total += b.pixels_total;
}

}  // namespace

std::string PipelineReport::summary() const {
  std::string s = fmt::format(
      "scans: {} integrated of {} ({} unreadable, {} outside the pose range)\n"
      "points: {} ({} dropped: {} NaN/Inf, {} no return, {} too close; {} beyond max range, cleared only)\n"
      "images: {} fused of {} ({} failed, {} outside the pose range, {} dropped on a full queue)\n"
      "fusion: {} voxel updates, {} occluded candidates, {:.1f}% of pixels on a voxel\n"
      "time: {:.1f} s total, {:.1f} s scans, {:.1f} s fusion, {:.1f} s feature extraction (worker)",
      scans_integrated, scans_total, scans_failed, scans_without_pose, points.points, points.dropped(),
      points.dropped_nonfinite, points.dropped_no_return, points.dropped_too_close, points.beyond_max_range,
      images_fused, images_total, images_failed, images_outside_pose_range, inference.dropped_queue_full,
      fusion.fused_voxels, fusion.occluded,
      fusion.pixels_total ? 100.0 * fusion.pixels_used / fusion.pixels_total : 0.0, seconds_total, seconds_scans,
      seconds_fusion, inference.busy_seconds);
  for (std::size_t i = 0; i < problems.size() && i < 20; ++i) s += "\n  skipped: " + problems[i];
  if (problems.size() > 20) s += fmt::format("\n  ... and {} more", problems.size() - 20);
  return s;
}

SemanticMap build_map(const Sequence& seq, FeatureSource* features, const PipelineOptions& options,
                      PipelineReport& report, const ProgressFn& progress) {
  const auto t_start = Clock::now();
  if (seq.poses.empty())
    throw Error(fmt::format("sequence {} has no poses (poses.txt); mapping needs a pose for every scan", seq.root.string()));
  SemanticMap result{options.map, {}, {}};
  result.info.model_id = features ? features->model_id() : "";
  result.info.source = seq.root.string();
  result.submaps.emplace_back(0, Pose::Identity(), options.map);
  Submap& submap = result.submaps.front();
  const Pose T_submap_world = submap.T_world_submap.inverse();
  ProjectiveFusion fusion(options.fusion);

  const std::size_t num_scans =
      options.max_scans ? std::min(options.max_scans, seq.scans.size()) : seq.scans.size();
  // Images after the last scan we map have no geometry to land on.
  const double last_stamp = num_scans ? seq.scans[num_scans - 1].stamp : -1e300;
  std::size_t num_images = 0;
  while (num_images < seq.images.size() && seq.images[num_images].stamp <= last_stamp) ++num_images;
  report.scans_total = num_scans;
  report.images_total = features ? num_images : 0;

  auto fuse_results = [&](std::vector<FeatureResult> results) {
    for (FeatureResult& r : results) {
      const auto& rec = r.job.record;
      const std::string name = (rec.rgb.empty() ? rec.labels : rec.rgb).filename().string();
      if (!r.error.empty()) {
        ++report.images_failed;
        report.problems.push_back(fmt::format("image {}: {}", name, r.error));
        continue;
      }
      const int dim = options.map.semantic.dim;
      if (r.features.dim != dim)
        throw Error(fmt::format("features for image {} have {} channels but the map stores {}-d embeddings "
                                "(set --dim to match the encoder)", name, r.features.dim, dim));
      const auto t0 = Clock::now();
      const CameraModel camera = seq.camera.scaled(r.features.width, r.features.height);
      add(report.fusion, fusion.fuse(submap.map, r.features, camera, T_submap_world * r.job.T_world_camera));
      report.seconds_fusion += seconds_since(t0);
      ++report.images_fused;
    }
  };

  std::unique_ptr<InferenceWorker> worker;
  if (features) worker = std::make_unique<InferenceWorker>(*features, options.queue_capacity);
  std::deque<ImageJob> backlog;
  auto submit_backlog = [&] {
    while (!backlog.empty() && worker->try_submit(backlog.front())) backlog.pop_front();
  };

  std::size_t si = 0, ii = 0;
  while (si < num_scans || ii < num_images) {
    const bool image_next = features && ii < num_images && (si >= num_scans || seq.images[ii].stamp < seq.scans[si].stamp);
    if (!features && si >= num_scans) break;
    if (image_next) {
      const ImageRecord& rec = seq.images[ii];
      const auto pose = seq.poses.at(rec.stamp);
      if (!pose) {
        ++report.images_outside_pose_range;
        report.problems.push_back(fmt::format("image at {:.3f} s: outside the pose time range", rec.stamp));
      } else {
        ImageJob job{ii, rec, *pose * seq.T_lidar_camera};
        if (!backlog.empty() || !worker->try_submit(job)) {
          if (options.policy == QueuePolicy::kBacklog) backlog.push_back(std::move(job));
          else worker->count_dropped();
        }
      }
      ++ii;
    } else {
      const ScanRecord& rec = seq.scans[si];
      const auto pose = seq.poses.at(rec.stamp);
      if (!pose) {
        ++report.scans_without_pose;
        report.problems.push_back(fmt::format("scan {}: outside the pose time range", rec.points.filename().string()));
      } else {
        try {
          const LidarScan scan = read_scan(rec);
          const auto t0 = Clock::now();
          report.points += submap.map.integrate_scan(scan.points, T_submap_world * *pose);
          report.seconds_scans += seconds_since(t0);
          ++report.scans_integrated;
        } catch (const Error& e) {
          ++report.scans_failed;
          report.problems.push_back(fmt::format("scan {}: {}", rec.points.filename().string(), e.what()));
        }
      }
      ++si;
      if (progress) progress(si, num_scans);
    }
    if (worker) {
      submit_backlog();
      fuse_results(worker->take_ready());
    }
  }
  if (worker) {
    while (!backlog.empty() || worker->in_flight() > 0) {
      submit_backlog();
      fuse_results(worker->wait_all());
    }
    fuse_results(worker->take_ready());
    report.inference = worker->stats();
  }
  report.seconds_total = seconds_since(t_start);
  return result;
}

}  // namespace slamvdb
