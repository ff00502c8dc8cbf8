#include "slamvdb/pipeline/mapping_pipeline.hpp"

#include <fmt/format.h>

#include <chrono>
#include <optional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/scan_io.hpp"

namespace slamvdb {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

std::string PipelineReport::summary() const {
  std::string s = fmt::format(
      "scans: {} integrated of {} ({} unreadable, {} outside the pose range)\n"
      "points: {} ({} dropped: {} NaN/Inf, {} no return, {} too close, {} outside the map extent; {} beyond max "
      "range, cleared only)\n"
      "images: {} fused of {} ({} failed, {} outside the pose range, {} before the first scan, {} dropped on a full "
      "queue)\n"
      "fusion: {} voxel updates, {} occluded candidates, {:.1f}% of pixels on a voxel; skipped feature pixels: {} "
      "non-finite, {} all-zero; {} frames refused as mostly invalid\n"
      "submaps: {}\n"
      "time: {:.1f} s total, {:.1f} s scans, {:.1f} s fusion, {:.1f} s feature extraction (worker)",
      scans_integrated, scans_total, scans_failed, scans_without_pose, points.points, points.dropped(),
      points.dropped_nonfinite, points.dropped_no_return, points.dropped_too_close, points.dropped_out_of_extent,
      points.beyond_max_range, images_fused, images_total, images_failed, images_outside_pose_range,
      images_before_first_scan, inference.dropped_queue_full,
      fusion.fused_voxels, fusion.occluded,
      fusion.pixels_total ? 100.0 * fusion.pixels_used / fusion.pixels_total : 0.0, fusion.pixels_nonfinite,
      fusion.pixels_zero, fusion.frames_refused_invalid, submaps, seconds_total, seconds_scans,
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
  SemanticMap result(options.map, MapInfo{features ? features->model_id() : "", "rellis3d", seq.root.string()});
  ProjectiveFusion fusion(options.fusion);

  const std::size_t num_scans =
      options.max_scans ? std::min(options.max_scans, seq.scans.size()) : seq.scans.size();
  // With --max-scans, the images after the last mapped scan are not part of the run; otherwise
  // every image is, and one beyond the poses is reported as such.
  std::size_t num_images = seq.images.size();
  if (options.max_scans) {
    const double last_stamp = num_scans ? seq.scans[num_scans - 1].stamp : -1e300;
    num_images = 0;
    while (num_images < seq.images.size() && seq.images[num_images].stamp <= last_stamp) ++num_images;
  }
  report.scans_total = num_scans;
  report.images_total = features ? num_images : 0;

  auto fuse = [&](FeatureResult& r) {
    const auto& rec = r.job.record;
    const std::string name = (rec.rgb.empty() ? rec.labels : rec.rgb).filename().string();
    if (!r.error.empty()) {
      ++report.images_failed;
      report.problems.push_back(fmt::format("image {}: {}", name, r.error));
      return;
    }
    const int dim = options.map.semantic.dim;
    if (r.features.dim != dim)
      throw Error(fmt::format("features for image {} have {} channels but the map stores {}-d embeddings "
                              "(set --dim to match the encoder)", name, r.features.dim, dim));
    const auto t0 = Clock::now();
    const CameraModel camera = seq.camera.scaled(r.features.width, r.features.height);
    FusionStats stats;
    const bool fused = result.update_active(
        rec.stamp, [&](VoxelMap& submap, const Pose& T_world_submap, std::span<const PlacedVoxelMap> finished) {
          const auto occluders = options.fusion.occlusion_from_other_submaps ? finished : std::span<const PlacedVoxelMap>{};
          stats = fusion.fuse(submap, r.features, camera, T_world_submap.inverse() * r.job.T_world_camera, occluders,
                              T_world_submap);
        });
    report.seconds_fusion += seconds_since(t0);
    if (!fused) {  // before the first scan there is no voxel to fuse into
      ++report.images_before_first_scan;
      return;
    }
    report.fusion += stats;
    if (stats.frames_refused_invalid) {
      ++report.images_failed;
      report.problems.push_back(fmt::format("image {}: refused, {} of its pixels on voxels have non-finite or zero "
                                            "features", name, stats.pixels_nonfinite + stats.pixels_zero));
      return;
    }
    ++report.images_fused;
  };

  // Camera poses are known up front (ground truth), so images outside the pose range are found
  // before any work is queued.
  std::vector<std::optional<Pose>> camera_poses(num_images);
  for (std::size_t i = 0; i < num_images; ++i) {
    if (const auto p = seq.poses.at(seq.images[i].stamp)) camera_poses[i] = *p * seq.T_lidar_camera;
  }
  std::unique_ptr<InferenceWorker> worker;
  if (features) worker = std::make_unique<InferenceWorker>(*features, options.queue_capacity);
  const bool replay = options.policy == QueuePolicy::kReplay;
  // Replay: images are queued ahead of the time line (the worker extracts while scans integrate)
  // and each is fused right after the scans that precede it, so the result is deterministic.
  std::size_t next_submit = 0;
  auto top_up = [&] {
    for (; next_submit < num_images; ++next_submit) {
      if (!camera_poses[next_submit]) continue;
      if (!worker->try_submit({next_submit, seq.images[next_submit], *camera_poses[next_submit]})) break;
    }
  };

  std::size_t si = 0, ii = 0;
  while (si < num_scans || (worker && ii < num_images)) {
    const bool image_next = worker && ii < num_images && (si >= num_scans || seq.images[ii].stamp < seq.scans[si].stamp);
    if (image_next) {
      if (!camera_poses[ii]) {
        ++report.images_outside_pose_range;
        report.problems.push_back(fmt::format("image at {:.3f} s: outside the pose time range", seq.images[ii].stamp));
      } else if (replay) {
        top_up();
        FeatureResult r = worker->next_result();
        fuse(r);
      } else if (!worker->try_submit({ii, seq.images[ii], *camera_poses[ii]})) {
        worker->count_dropped();
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
          report.points += result.integrate_scan(rec.stamp, scan.points, *pose);
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
    if (worker && replay) top_up();
    if (worker && !replay)
      for (FeatureResult& r : worker->take_ready()) fuse(r);
  }
  if (worker) {
    for (FeatureResult& r : worker->wait_all()) fuse(r);
    report.inference = worker->stats();
  }
  result.finish_active_submap();
  report.submaps = result.num_submaps();
  report.seconds_total = seconds_since(t_start);
  return result;
}

}  // namespace slamvdb
