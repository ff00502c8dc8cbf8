#include "slamvdb/pipeline/inference_worker.hpp"

#include <chrono>
#include <exception>

namespace slamvdb {

InferenceWorker::InferenceWorker(FeatureSource& source, std::size_t capacity)
    : source_(source), capacity_(capacity == 0 ? 1 : capacity), thread_([this] { run(); }) {}

InferenceWorker::~InferenceWorker() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  thread_.join();
}

bool InferenceWorker::try_submit(ImageJob job) {
  {
    std::lock_guard lock(mutex_);
    if (queue_.size() >= capacity_) return false;
    queue_.push_back(std::move(job));
    ++stats_.submitted;
  }
  work_cv_.notify_one();
  return true;
}

void InferenceWorker::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_cv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    FeatureResult result{std::move(queue_.front()), {}, {}};
    queue_.pop_front();
    ++busy_;
    lock.unlock();
    const auto t0 = std::chrono::steady_clock::now();
    try {
      result.features = source_.features_for(result.job.record);
    } catch (const std::exception& e) {
      result.error = e.what();
    }
    const double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    lock.lock();
    --busy_;
    stats_.busy_seconds += dt;
    ++(result.error.empty() ? stats_.completed : stats_.failed);
    ready_.push_back(std::move(result));
    done_cv_.notify_all();
  }
}

std::vector<FeatureResult> InferenceWorker::take_ready() {
  std::lock_guard lock(mutex_);
  return std::exchange(ready_, {});
}

FeatureResult InferenceWorker::next_result() {
  std::unique_lock lock(mutex_);
  done_cv_.wait(lock, [&] { return !ready_.empty(); });
  FeatureResult r = std::move(ready_.front());
  ready_.erase(ready_.begin());
  return r;
}

std::vector<FeatureResult> InferenceWorker::wait_all() {
  std::unique_lock lock(mutex_);
  done_cv_.wait(lock, [&] { return queue_.empty() && busy_ == 0; });
  return std::exchange(ready_, {});
}

std::size_t InferenceWorker::in_flight() const {
  std::lock_guard lock(mutex_);
  return queue_.size() + busy_;
}

InferenceStats InferenceWorker::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace slamvdb
