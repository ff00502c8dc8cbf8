#pragma once
// Runs feature extraction on its own thread behind a bounded queue, so the mapping loop never
// waits for a network. What happens to a frame when the queue is full is a policy, and every
// frame's fate is counted.
#include <condition_variable>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "slamvdb/pipeline/feature_source.hpp"

namespace slamvdb {

struct ImageJob {
  std::size_t index = 0;  // position in the sequence's image list
  ImageRecord record;
  Pose T_world_camera = Pose::Identity();
};

struct FeatureResult {
  ImageJob job;
  FeatureMap features;
  std::string error;  // non-empty when extraction failed; features are then empty
};

enum class QueuePolicy {
  kDropWhenFull,  // live operation: a frame that finds the queue full is dropped and counted
  kReplay,        // replay: every frame is extracted (ahead of time) and fused at its place in the
                  // time line, so the map does not depend on timing and no frame is lost
};

struct InferenceStats {
  std::size_t submitted = 0, completed = 0, failed = 0, dropped_queue_full = 0;
  double busy_seconds = 0.0;
};

class InferenceWorker {
 public:
  InferenceWorker(FeatureSource& source, std::size_t capacity);
  ~InferenceWorker();
  InferenceWorker(const InferenceWorker&) = delete;
  InferenceWorker& operator=(const InferenceWorker&) = delete;

  // Never blocks. Returns false when the queue is full (the caller applies its policy).
  bool try_submit(ImageJob job);
  void count_dropped() { ++stats_.dropped_queue_full; }
  std::vector<FeatureResult> take_ready();   // never blocks
  FeatureResult next_result();               // blocks; results come in submission order
  std::vector<FeatureResult> wait_all();     // blocks until every submitted job is done
  std::size_t in_flight() const;
  InferenceStats stats() const;

 private:
  void run();

  FeatureSource& source_;
  std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable work_cv_, done_cv_;
  std::deque<ImageJob> queue_;
  std::vector<FeatureResult> ready_;
  std::size_t busy_ = 0;
  bool stop_ = false;
  InferenceStats stats_;
  std::thread thread_;
};

}  // namespace slamvdb
