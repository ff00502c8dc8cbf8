// The Mapper's input side: construction, admission of scans, images and poses into the bounded
// queues (order and coverage checks, waits), and the counts of what could not be read. The worker
// threads are in mapper_workers.cpp, the submap side in mapper_submaps.cpp.
#include "slamvdb/pipeline/mapper.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/pipeline/mapper_item.hpp"

namespace slamvdb {

using mapper_detail::Clock;
using mapper_detail::seconds_since;

namespace {

double resume_point(const SemanticMap& map) {
  double t = -std::numeric_limits<double>::infinity();
  for (const SubmapInfo& s : map.submaps())
    if (!s.time_range.empty()) t = std::max(t, s.time_range.end);
  return t;
}

}  // namespace

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

}  // namespace slamvdb
