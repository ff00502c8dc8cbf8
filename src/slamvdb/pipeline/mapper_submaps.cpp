// The Mapper's submap side: handing finished submaps to the store, letting far ones leave memory
// and bringing them back, loop-closure corrections and merges, and the end of a run.
#include <fmt/format.h>

#include <algorithm>

#include "slamvdb/core/error.hpp"
#include "slamvdb/pipeline/mapper.hpp"

namespace slamvdb {

void Mapper::after_scan(const Pose& T_world_lidar, std::optional<int> finished_id) {
  {
    // The most submaps memory held: here, with the one just finished and the new active one.
    const std::size_t in_memory = map_.num_submaps();
    std::lock_guard lock(mutex_);
    report_.peak_submaps_in_memory = std::max(report_.peak_submaps_in_memory, in_memory);
  }
  if (!store_) return;
  std::lock_guard store_lock(store_mutex_);
  // A loop closer may have merged the just-finished submap into another before this (its merge
  // wrote the target to the store, with this one's voxels): then there is nothing left to save.
  if (finished_id && map_.submap_info(*finished_id)) store_->save_finished(map_, *finished_id);
  if (options_.unload_radius <= 0) return;
  const Vec3d robot = T_world_lidar.translation();
  auto distance = [&](const SubmapInfo& s) { return (s.T_world_submap.translation() - robot).norm(); };
  // Every finished submap in memory is already in the store (saved when it finished, or loaded
  // from it, and kept in step by corrections and merges), so letting it go loses nothing.
  std::size_t unloaded = 0, reloaded = 0;
  for (const SubmapInfo& s : map_.submaps())
    if (s.finished && distance(s) > options_.unload_radius) {
      map_.remove_finished_submap(s.id);
      unloaded_[s.id] = s;
      ++unloaded;
    }
  std::vector<int> near;
  for (const auto& [id, s] : unloaded_)
    if (distance(s) < 0.8 * options_.unload_radius) near.push_back(id);
  for (const int id : near) reload_submap(id), ++reloaded;
  if (unloaded || reloaded) {
    std::lock_guard lock(mutex_);
    report_.submaps_unloaded += unloaded;
    report_.submaps_reloaded += reloaded;
  }
}

void Mapper::reload_submap(int id) {
  auto [info, voxels] = store_->load(id);
  info.T_world_submap = unloaded_.at(id).T_world_submap;
  map_.add_finished_submap(info, std::move(voxels));
  unloaded_.erase(id);
}

void Mapper::correct_submaps(const std::map<int, Pose>& T_world_submap) {
  std::lock_guard store_lock(store_mutex_);
  // A submap out of memory takes its new anchor where it waits and in the store, and is read back
  // with it when needed: a loop closer moves every submap, and reading them all back would undo
  // the unloading at every loop.
  std::map<int, Pose> in_memory;
  for (const auto& [id, T] : T_world_submap)
    if (unloaded_.contains(id)) check_submap_pose(id, T);
    else in_memory.emplace(id, T);
  map_.set_submap_poses(in_memory);  // checks the rest before anything moves
  for (const auto& [id, T] : T_world_submap)
    if (const auto it = unloaded_.find(id); it != unloaded_.end()) it->second.T_world_submap = T;
  if (store_) store_->save_poses(T_world_submap);
}

std::vector<SubmapInfo> Mapper::submaps() const {
  std::lock_guard store_lock(store_mutex_);
  std::vector<SubmapInfo> all = map_.submaps();
  for (const auto& [id, info] : unloaded_) all.push_back(info);
  std::sort(all.begin(), all.end(), [](const SubmapInfo& a, const SubmapInfo& b) { return a.id < b.id; });
  return all;
}

MergeReport Mapper::merge_submaps(int target, int source, const MergeOptions& options) {
  std::lock_guard store_lock(store_mutex_);
  std::size_t reloaded = 0;
  for (const int id : {target, source})
    if (unloaded_.contains(id)) reload_submap(id), ++reloaded;
  const MergeReport report = map_.merge_submaps(target, source, options);
  if (report.refused.empty() && store_) store_->save_merge(map_, target, source);
  std::lock_guard lock(mutex_);
  report_.submaps_reloaded += reloaded;
  return report;
}

bool Mapper::failed() const {
  std::lock_guard lock(mutex_);
  return error_ != nullptr;
}

void Mapper::end_mapping() {
  {
    std::lock_guard lock(mutex_);
    if (closing_) throw Error("the mapper has already finished");
    closing_ = true;
    wake_all();
  }
  mapping_thread_.join();
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    wake_all();
  }
  if (inference_thread_.joinable()) inference_thread_.join();
  if (error_) std::rethrow_exception(error_);
  const std::optional<int> active = map_.active_submap_id();
  map_.finish_active_submap();
  std::lock_guard store_lock(store_mutex_);
  if (store_ && active) store_->save_finished(map_, *active);
  ended_ = true;
}

SemanticMap Mapper::finish() {
  if (taken_) throw Error("the mapper has already finished");
  if (!ended_) end_mapping();
  taken_ = true;
  std::lock_guard store_lock(store_mutex_);
  std::lock_guard lock(mutex_);
  report_.submaps = map_.num_submaps() + unloaded_.size();
  report_.submaps_in_memory_at_end = map_.num_submaps();
  return std::move(map_);
}

PipelineReport Mapper::report() const {
  std::lock_guard lock(mutex_);
  return report_;
}

}  // namespace slamvdb
