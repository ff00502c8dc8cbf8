#pragma once
// The streaming mapper (paper section 6.2.1, Figure 6.1). Scans, images (or finished feature maps)
// and poses arrive asynchronously, from any threads, at their own rates. The mapper integrates
// every scan and fuses every image as soon as the trajectory, which grows as poses arrive, covers
// its stamp, strictly in stamp order (a scan before an image of the same stamp), so a replay gives
// the same map whatever the timing. Loop-closure corrections and merges may come at any time.
//
// Threads: the callers'; one mapping thread (scans, fusion, checkpoints); one inference thread
// when images come with a FeatureSource. Queued items (scans, images and their feature maps) are
// bounded in count and in bytes. Every item is used or counted under the reason it was not: queue
// full (kDropWhenFull), no pose ever covering its stamp, a stamp not after the previous one of its
// stream (out of order, duplicate), already in the map a run resumes.
//
// Waiting: poses only ever extend the trajectory at its end, so an item before the first pose, or
// after the last once end_poses() was called, can never be covered; it is counted at once and never
// waits for room (nor holds any). Whatever else waits for a pose is ended by a pose or end_poses();
// a caller that gives the poses itself must give each one no later than the first item it covers
// (a replay knows the whole trajectory: mapping_pipeline.cpp), or a full queue can only end in
// max_wait_seconds.
//
// With a SubmapStore, each finished submap is handed to it at once (a map file that then holds it
// whatever happens later), and finished submaps farther than unload_radius from the robot leave
// memory and are read back when the robot comes near again or a correction or merge needs them.
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <thread>
#include <vector>

#include "slamvdb/fusion/camera_model.hpp"
#include "slamvdb/fusion/projective_fusion.hpp"
#include "slamvdb/fusion/trajectory.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/map/submap_store.hpp"
#include "slamvdb/pipeline/feature_source.hpp"
#include "slamvdb/pipeline/mapping_report.hpp"

namespace slamvdb {

// The unload radius `map` and `slam` use unless told otherwise (metres). A finished submap's voxels
// lie within its length (50 m) plus the LiDAR's range (100 m) of its anchor, and fusion looks
// 40 m from the camera (FusionParams::max_depth), so at the default options a submap farther
// than 190 m can change nothing the mapper does: unloading it leaves the map as it would be, with
// `--occlusion all` too. Measured in the README ("Memory on long drives").
inline constexpr double kDefaultUnloadRadius = 200.0;

struct MapperOptions {
  MapParams map;
  FusionParams fusion;
  CameraModel camera;                       // intrinsics at full image resolution
  Pose T_lidar_camera = Pose::Identity();   // the camera in the LiDAR frame (poses are the LiDAR's)
  QueuePolicy policy = QueuePolicy::kReplay;
  // kReplay: how long the mapper may wait for a pose while callers wait for room. A pose from
  // another thread ends such a wait; one that only a waiting caller could give never would, so
  // once the mapper has waited this long since it last got a pose (one clock, not one per item),
  // items that find the queue full are dropped at once (counted as queue full) until a pose comes.
  double max_wait_seconds = 60.0;
  std::size_t max_queued_items = 16;                  // scans + images waiting, feature maps included
  std::size_t max_queued_bytes = std::size_t{1} << 30;  // their points and feature maps
  // Finished submaps whose anchor is farther than this from the robot leave memory (0: never);
  // they come back within 0.8 of it. Needs a SubmapStore. The CLI's default: kDefaultUnloadRadius.
  double unload_radius = 0;
};

class Mapper {
 public:
  // `map` is where mapping starts: empty, or a map loaded to resume a run (items up to the end of
  // its last submap's time range are then counted as resumed and skipped). `features` (images by
  // record) and `store` may be null; both must outlive the mapper.
  Mapper(const MapperOptions& options, SemanticMap map, FeatureSource* features = nullptr,
         SubmapStore* store = nullptr);
  ~Mapper();  // stops the threads; anything not yet processed is discarded
  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;

  // ---- input (any thread). False: the item was not taken (counted in the report with why). ----
  bool add_scan(double stamp, std::vector<Vec3f> points_sensor);
  bool add_image(const ImageRecord& record);            // features from the FeatureSource
  bool add_features(double stamp, FeatureMap features);  // features computed elsewhere
  bool add_pose(double stamp, const Pose& T_world_sensor);  // never waits
  // No more poses will come (e.g. a replay has given its last): items after the last pose are
  // counted as outside the pose range at once instead of waiting.
  void end_poses();
  // An item the caller could not even read (a corrupt scan file, ...): counted as failed.
  void add_unreadable_scan(const std::string& problem);
  void add_unreadable_image(const std::string& problem);

  // Blocks until the mapper has processed everything it was given that the poses so far cover
  // (what waits for a later pose stays queued), or it failed or finished. A loop closer calls it
  // before reading the submaps to correct, so that every scan it has given is in one of them.
  void wait_until_idle();

  // ---- loop closure (any thread) ----
  // Moves submaps, in memory or not (one out of memory takes its new anchor in the store and
  // comes back with it: a correction reads nothing back). Throws Error like SemanticMap, before
  // anything is moved.
  void correct_submaps(const std::map<int, Pose>& T_world_submap);
  // Reads the two submaps back first when they left memory.
  MergeReport merge_submaps(int target, int source, const MergeOptions& options = {});
  // Every submap of the map, in memory or only in the store, by id (a loop closer's view).
  std::vector<SubmapInfo> submaps() const;

  // Processes what can be, counts what no pose covers, finishes the active submap (handing it to
  // the store) and stops the threads. Corrections and merges still work after it (the last
  // submap's loops); finish() calls it if the caller has not.
  void end_mapping();
  // Returns the map (the submaps still in memory; the store holds them all).
  SemanticMap finish();
  PipelineReport report() const;  // a snapshot
  // Readers may use the map while mapping goes on (SemanticMap's locks make that safe).
  const SemanticMap& map() const { return map_; }
  // The first error of the mapping thread (a store that cannot write, ...), rethrown by finish().
  bool failed() const;

 private:
  struct Item;
  // Counts a new item of the scan or image stream and checks its stamp. Returns the answer for the
  // caller when the item goes no further (false: refused, counted with why; true: already in the
  // resumed map); nothing when it is to be queued.
  std::optional<bool> screen(bool scan, double stamp);
  bool admit(std::unique_lock<std::mutex>& lock, std::unique_ptr<Item> item);
  // No pose can ever cover `stamp`: before the first pose (the trajectory only grows at its end),
  // or after the last one once the poses have ended.
  bool never_covered(double stamp) const;
  void count_outside_pose_range(const Item& item);
  // Every state change a waiter may be waiting for (an item queued or taken, a feature map done,
  // a pose, the end of poses, finishing, an error) wakes every waiter; each rechecks its own
  // condition, so no change can be missed by the thread it concerns.
  void wake_all();
  void mapping_loop();
  void inference_loop();
  Item* next_item() const;
  void process(Item& item, const Pose& T_world_lidar);
  void after_scan(const Pose& T_world_lidar, std::optional<int> finished_id);
  void reload_submap(int id);  // store_mutex_ held

  MapperOptions options_;
  SemanticMap map_;
  FeatureSource* features_;
  SubmapStore* store_;
  ProjectiveFusion fusion_;
  double resume_after_ = -std::numeric_limits<double>::infinity();

  mutable std::mutex mutex_;  // everything below up to store_mutex_
  // work_cv_: the mapping thread; encoder_cv_: the inference thread; room_cv_: callers waiting
  // for room; idle_cv_: wait_until_idle.
  std::condition_variable work_cv_, encoder_cv_, room_cv_, idle_cv_;
  std::deque<std::unique_ptr<Item>> scans_, images_;
  std::size_t queued_bytes_ = 0;
  Trajectory trajectory_;
  double last_scan_stamp_, last_image_stamp_;
  bool closing_ = false, stopping_ = false, poses_ended_ = false;
  // Since when the mapping thread has waited for a pose to cover its next item (reset by every
  // pose and every item taken); nothing while it does not wait for one.
  std::optional<std::chrono::steady_clock::time_point> waiting_for_pose_since_;
  // The mapping thread waits with nothing it can process; any new input clears it.
  bool idle_ = false;
  PipelineReport report_;
  std::exception_ptr error_;
  // Feature maps already fused, whose buffers the inference thread fills again (at most
  // kSpareFeatureMaps; they count against max_queued_bytes like queued ones).
  static constexpr std::size_t kSpareFeatureMaps = 2;
  std::vector<FeatureMap> spare_features_;

  mutable std::mutex store_mutex_;  // the store and the submaps that left memory
  std::map<int, SubmapInfo> unloaded_;
  bool ended_ = false, taken_ = false;  // end_mapping() done; finish() done (the caller's thread)

  std::thread mapping_thread_, inference_thread_;
};

}  // namespace slamvdb
