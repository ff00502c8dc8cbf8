// The Mapper's two worker threads: the inference thread encodes queued images, the mapping
// thread integrates scans and images in stamp order once their poses are known.
#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/pipeline/mapper_item.hpp"

namespace slamvdb {

using mapper_detail::Clock;
using mapper_detail::seconds_since;

// ---- the two worker threads ----

Mapper::Item* Mapper::next_item() const {
  Item* scan = scans_.empty() ? nullptr : scans_.front().get();
  Item* image = images_.empty() ? nullptr : images_.front().get();
  if (!scan || !image) return scan ? scan : image;
  return image->stamp < scan->stamp ? image : scan;  // a scan first at equal stamps
}

void Mapper::inference_loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    Item* job = nullptr;
    encoder_cv_.wait(lock, [&] {
      if (stopping_) return true;
      job = nullptr;
      for (auto& item : images_)
        if (item->state == Item::State::kWaitingForEncoder) {
          job = item.get();
          break;
        }
      if (!job) return false;
      // Results count against the bound too (a spare buffer it would fill again counts once);
      // the mapper's very next item is always encoded, or nothing could ever free the queue.
      // Both change when the mapping thread takes an item, which wakes this thread (wake_all).
      const std::size_t reusable = spare_features_.empty() ? 0 : spare_features_.back().bytes();
      return queued_bytes_ - reusable <= options_.max_queued_bytes || job == next_item();
    });
    if (stopping_) return;
    job->state = Item::State::kEncoding;
    FeatureMap features;
    if (!spare_features_.empty()) {
      features = std::move(spare_features_.back());
      spare_features_.pop_back();
      queued_bytes_ -= features.bytes();
    }
    lock.unlock();
    const auto t0 = Clock::now();
    std::string error;
    try {
      features_->features_into(*job->record, features);
    } catch (const std::exception& e) {
      error = e.what();
      features = FeatureMap();
    }
    const double dt = seconds_since(t0);
    lock.lock();
    report_.inference.busy_seconds += dt;
    ++(error.empty() ? report_.inference.completed : report_.inference.failed);
    job->bytes = features.bytes();
    queued_bytes_ += job->bytes;
    report_.peak_queued_bytes = std::max(report_.peak_queued_bytes, queued_bytes_);
    job->features = std::move(features);
    job->error = std::move(error);
    job->state = Item::State::kReady;
    wake_all();
  }
}

void Mapper::mapping_loop() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    Item* next = next_item();
    if (!next || next->state != Item::State::kReady) waiting_for_pose_since_.reset();
    if (!next) {
      idle_ = true;
      idle_cv_.notify_all();
      if (closing_) return;
      work_cv_.wait(lock);
      continue;
    }
    if (next->state != Item::State::kReady) {  // its features are being computed
      work_cv_.wait(lock);
      continue;
    }
    const std::optional<Pose> pose = trajectory_.at(next->stamp);
    if (!pose && !closing_ && !never_covered(next->stamp)) {  // a later pose will cover it
      if (!waiting_for_pose_since_) {
        waiting_for_pose_since_ = Clock::now();
        room_cv_.notify_all();  // callers waiting for room now wait at most max_wait_seconds
      }
      idle_ = true;
      idle_cv_.notify_all();
      work_cv_.wait(lock);
      continue;
    }
    waiting_for_pose_since_.reset();
    auto& queue = next->is_scan ? scans_ : images_;
    std::unique_ptr<Item> item = std::move(queue.front());
    queue.pop_front();
    queued_bytes_ -= item->bytes;
    wake_all();  // room for callers; a new next item and bound for the encoder
    if (!pose) {  // before the first pose, or after the last one at the end of the run
      count_outside_pose_range(*item);
      continue;
    }
    lock.unlock();
    try {
      process(*item, *pose);
    } catch (...) {
      lock.lock();
      error_ = std::current_exception();
      stopping_ = true;
      wake_all();
      return;
    }
    lock.lock();
    const std::size_t spare_bytes = item->features.bytes();
    if (!item->is_scan && features_ && spare_features_.size() < kSpareFeatureMaps && spare_bytes > 0 &&
        queued_bytes_ + spare_bytes <= options_.max_queued_bytes) {
      queued_bytes_ += spare_bytes;
      spare_features_.push_back(std::move(item->features));
    }
  }
}

void Mapper::process(Item& item, const Pose& T_world_lidar) {
  const auto t0 = Clock::now();
  if (item.is_scan) {
    const std::optional<int> before = map_.active_submap_id();
    ScanIntegrationStats stats;
    std::string problem;
    try {
      stats = map_.integrate_scan(item.stamp, item.points, T_world_lidar);
    } catch (const Error& e) {
      problem = e.what();
    }
    const std::optional<int> after = map_.active_submap_id();
    {
      std::lock_guard lock(mutex_);
      report_.seconds_scans += seconds_since(t0);
      if (problem.empty()) report_.points += stats, ++report_.scans_integrated;
      else ++report_.scans_failed, report_.add_problem(fmt::format("{}: {}", item.name(), problem));
    }
    after_scan(T_world_lidar, before && before != after ? before : std::nullopt);
    return;
  }
  const int dim = options_.map.semantic.dim;
  if (item.error.empty() && item.features.dim() != dim)  // every frame would fail: a configuration error
    throw Error(fmt::format("features for {} have {} channels but the map stores {}-d embeddings (set --dim to match "
                            "the encoder)", item.name(), item.features.dim(), dim));
  FusionStats stats;
  bool fused = false;
  if (item.error.empty()) {
    const CameraModel camera = options_.camera.scaled(item.features.width(), item.features.height());
    const bool moving = item.record && item.record->T_lidar_camera;  // extrinsics at the image's stamp
    const Pose T_world_camera = T_world_lidar * (moving ? *item.record->T_lidar_camera : options_.T_lidar_camera);
    const bool all = options_.fusion.occlusion_from_other_submaps;
    fused = map_.update_active(
        item.stamp, [&](VoxelMap& submap, const Pose& T_world_submap, std::span<const PlacedVoxelMap> finished) {
          stats = fusion_.fuse(submap, item.features, camera, T_world_submap.inverse() * T_world_camera,
                               all ? finished : std::span<const PlacedVoxelMap>{}, T_world_submap);
        });
  }
  std::lock_guard lock(mutex_);
  report_.seconds_fusion += seconds_since(t0);
  if (!item.error.empty()) {
    ++report_.images_failed;
    report_.add_problem(fmt::format("{}: {}", item.name(), item.error));
  } else if (!fused) {  // before the first scan there is no voxel to fuse into
    ++report_.images_before_first_scan;
  } else if (report_.fusion += stats, stats.frames_refused_invalid) {
    ++report_.images_failed;
    report_.add_problem(fmt::format("{}: refused, {} of its pixels on voxels have non-finite or zero features",
                                    item.name(), stats.pixels_nonfinite + stats.pixels_zero));
  } else {
    ++report_.images_fused;
  }
}

}  // namespace slamvdb
