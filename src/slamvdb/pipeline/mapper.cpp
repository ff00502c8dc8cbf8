#include "slamvdb/pipeline/mapper.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double resume_point(const SemanticMap& map) {
  double t = -std::numeric_limits<double>::infinity();
  for (const SubmapInfo& s : map.submaps())
    if (!s.time_range.empty()) t = std::max(t, s.time_range.end);
  return t;
}

}  // namespace

struct Mapper::Item {
  enum class State { kWaitingForEncoder, kEncoding, kReady };
  bool is_scan = true;
  double stamp = 0;
  std::vector<Vec3f> points;
  std::optional<ImageRecord> record;  // an image the inference thread still has to encode
  FeatureMap features;
  State state = State::kReady;
  std::string error;  // extraction failed
  std::size_t bytes = 0;

  std::string name() const {
    if (record && !(record->rgb.empty() && record->labels.empty()))
      return fmt::format("image {}", (record->rgb.empty() ? record->labels : record->rgb).filename().string());
    return fmt::format("{} at {:.6f} s", is_scan ? "scan" : "image", stamp);
  }
};

Mapper::Mapper(const MapperOptions& options, SemanticMap map, FeatureSource* features, SubmapStore* store)
    : options_(options), map_(std::move(map)), features_(features), store_(store), fusion_(options.fusion),
      last_scan_stamp_(-std::numeric_limits<double>::infinity()),
      last_image_stamp_(-std::numeric_limits<double>::infinity()) {
  if (options_.max_queued_items < 1 || !(options_.max_wait_seconds >= 0))  // else a caller could wait for ever
    throw Error(fmt::format("mapper queue of {} items, wait of {} s: expected at least 1 item and a wait >= 0",
                            options_.max_queued_items, options_.max_wait_seconds));
  if (options_.unload_radius > 0 && !store_)
    throw Error("submaps can leave memory (unload radius) only when they are kept in a store (a map file)");
  resume_after_ = resume_point(map_);
  mapping_thread_ = std::thread([this] { mapping_loop(); });
  if (features_) inference_thread_ = std::thread([this] { inference_loop(); });
}

Mapper::~Mapper() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_all();
  if (mapping_thread_.joinable()) mapping_thread_.join();
  if (inference_thread_.joinable()) inference_thread_.join();
}

// ---- input ----

bool Mapper::never_covered(double stamp) const {
  if (!trajectory_.empty() && stamp < trajectory_.front_stamp()) return true;
  return poses_ended_ && (trajectory_.empty() || stamp > trajectory_.back_stamp());
}

void Mapper::count_outside_pose_range(const Item& item) {
  ++(item.is_scan ? report_.scans_without_pose : report_.images_outside_pose_range);
  report_.add_problem(fmt::format("{}: outside the pose time range", item.name()));
}

void Mapper::wake_all() {
  work_cv_.notify_all();
  encoder_cv_.notify_all();
  room_cv_.notify_all();
  idle_cv_.notify_all();
}

bool Mapper::admit(std::unique_lock<std::mutex>& lock, std::unique_ptr<Item> item) {
  const bool scan = item->is_scan;
  auto full = [&] {
    const std::size_t count = scans_.size() + images_.size();
    return count + 1 > options_.max_queued_items || (count > 0 && queued_bytes_ + item->bytes > options_.max_queued_bytes);
  };
  // Replay waits for room, but not for an item no pose can cover (counted below, it takes none),
  // and not once the mapper has waited max_wait_seconds for a pose: only a caller could give it.
  if (options_.policy == QueuePolicy::kReplay) {
    const auto limit = std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(std::min(options_.max_wait_seconds, 1e9)));
    while (full() && !stopping_ && !closing_ && !error_ && !never_covered(item->stamp)) {
      if (!waiting_for_pose_since_) room_cv_.wait(lock);  // the mapper is working: room will come
      else if (Clock::now() - *waiting_for_pose_since_ >= limit) break;
      else room_cv_.wait_until(lock, *waiting_for_pose_since_ + limit);
    }
  }
  if (error_) return false;  // the mapping thread failed: finish() reports why
  if (stopping_ || closing_) throw Error("the mapper has finished; it takes no more input");
  if (never_covered(item->stamp)) {
    count_outside_pose_range(*item);
    return false;
  }
  if (full()) {
    ++(scan ? report_.scans_queue_full : report_.inference.dropped_queue_full);
    report_.add_problem(fmt::format(
        "{}: dropped, the mapper's queue is full ({} items, {:.0f} MB){}", item->name(), scans_.size() + images_.size(),
        queued_bytes_ / 1e6,
        waiting_for_pose_since_ ? fmt::format(" and has waited {:.1f} s for a pose that has not come",
                                              seconds_since(*waiting_for_pose_since_))
                                : ""));
    return false;
  }
  queued_bytes_ += item->bytes;
  idle_ = false;
  (scan ? scans_ : images_).push_back(std::move(item));
  report_.peak_queued_items = std::max(report_.peak_queued_items, scans_.size() + images_.size());
  report_.peak_queued_bytes = std::max(report_.peak_queued_bytes, queued_bytes_);
  wake_all();
  return true;
}

namespace {
// Per stream, stamps must increase: a repeated stamp is a duplicate, an earlier one out of order.
// Returns the reason an item is refused, or nothing.
const char* stream_order_problem(double stamp, double& last) {
  if (!std::isfinite(stamp)) return "its time stamp is not finite";
  if (stamp == last) return "duplicate time stamp";
  if (stamp < last) return "time stamp before the previous one of its stream";
  last = stamp;
  return nullptr;
}
}  // namespace

std::optional<bool> Mapper::screen(bool scan, double stamp) {
  ++(scan ? report_.scans_total : report_.images_total);
  double& last = scan ? last_scan_stamp_ : last_image_stamp_;
  const bool duplicate = stamp == last;
  if (const char* problem = stream_order_problem(stamp, last)) {
    if (scan) ++(duplicate ? report_.scans_duplicate : report_.scans_out_of_order);
    else ++(duplicate ? report_.images_duplicate : report_.images_out_of_order);
    report_.add_problem(fmt::format("{} at {:.6f} s: {}", scan ? "scan" : "image", stamp, problem));
    return false;
  }
  if (stamp <= resume_after_) {
    ++(scan ? report_.scans_resumed : report_.images_resumed);
    return true;
  }
  return std::nullopt;
}

bool Mapper::add_scan(double stamp, std::vector<Vec3f> points_sensor) {
  std::unique_lock lock(mutex_);
  if (const auto answer = screen(true, stamp)) return *answer;
  auto item = std::make_unique<Item>();
  item->stamp = stamp;
  item->bytes = points_sensor.size() * sizeof(Vec3f);
  item->points = std::move(points_sensor);
  return admit(lock, std::move(item));
}

bool Mapper::add_image(const ImageRecord& record) {
  if (!features_) throw Error("this mapper has no feature source: give images as feature maps (add_features)");
  std::unique_lock lock(mutex_);
  if (const auto answer = screen(false, record.stamp)) return *answer;
  auto item = std::make_unique<Item>();
  item->is_scan = false;
  item->stamp = record.stamp;
  item->record = record;
  item->state = Item::State::kWaitingForEncoder;
  return admit(lock, std::move(item));
}

bool Mapper::add_features(double stamp, FeatureMap features) {
  std::unique_lock lock(mutex_);
  if (const auto answer = screen(false, stamp)) return *answer;
  auto item = std::make_unique<Item>();
  item->is_scan = false;
  item->stamp = stamp;
  item->bytes = features.bytes();
  item->features = std::move(features);
  return admit(lock, std::move(item));
}

bool Mapper::add_pose(double stamp, const Pose& T_world_sensor) {
  std::lock_guard lock(mutex_);
  ++report_.poses_total;
  const Eigen::Matrix3d R = T_world_sensor.linear();
  if (!T_world_sensor.matrix().allFinite() || (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      std::abs(R.determinant() - 1) > 1e-6) {
    ++report_.poses_invalid;
    report_.add_problem(fmt::format("pose at {:.6f} s: not a finite rigid transform", stamp));
    return false;
  }
  if (std::isfinite(stamp) && !trajectory_.empty() && stamp <= trajectory_.back_stamp()) {
    ++(stamp == trajectory_.back_stamp() ? report_.poses_duplicate : report_.poses_out_of_order);
    report_.add_problem(fmt::format("pose at {:.6f} s: {}", stamp,
                                    stamp == trajectory_.back_stamp() ? "duplicate time stamp"
                                                                      : "time stamp before the previous pose"));
    return false;
  }
  if (!std::isfinite(stamp)) {
    ++report_.poses_invalid;
    report_.add_problem("pose with a time stamp that is not finite");
    return false;
  }
  if (poses_ended_) {
    ++report_.poses_out_of_order;
    report_.add_problem(fmt::format("pose at {:.6f} s: after the end of the poses was announced", stamp));
    return false;
  }
  trajectory_.append(stamp, T_world_sensor);
  idle_ = false;
  waiting_for_pose_since_.reset();  // the mapping thread starts the clock again if it still waits
  wake_all();
  return true;
}

void Mapper::wait_until_idle() {
  std::unique_lock lock(mutex_);
  idle_cv_.wait(lock, [&] { return idle_ || stopping_ || error_ != nullptr; });
}

void Mapper::end_poses() {
  std::lock_guard lock(mutex_);
  poses_ended_ = true;
  idle_ = false;
  wake_all();
}

void Mapper::add_unreadable_scan(const std::string& problem) {
  std::lock_guard lock(mutex_);
  ++report_.scans_total, ++report_.scans_failed;
  report_.add_problem(problem);
}

void Mapper::add_unreadable_image(const std::string& problem) {
  std::lock_guard lock(mutex_);
  ++report_.images_total, ++report_.images_failed;
  report_.add_problem(problem);
}

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
