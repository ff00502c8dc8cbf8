#include "slamvdb/server/compute_gate.hpp"

#include <algorithm>
#include <chrono>
#include <thread>

namespace slamvdb {

ComputeGate::ComputeGate(std::size_t slots)
    : slots_(slots ? slots : std::max<std::size_t>(1, std::thread::hardware_concurrency())) {}

ComputeGate::Pass ComputeGate::enter(const Deadline& deadline) {
  std::unique_lock lock(mutex_);
  if (queue_.empty() && held_ < slots_) {
    ++held_;
    return Pass(*this);
  }
  // The slot is handed over by release() (held_ does not change), so a request arriving between
  // a release and the waiter's wake-up cannot take it first.
  const auto me = queue_.emplace(queue_.end());
  const auto admitted = [&] { return me->admitted; };
  if (deadline.set()) me->woken.wait_until(lock, deadline.at(), admitted);  // wakes when admitted or at the deadline
  else me->woken.wait(lock, admitted);
  const bool got = me->admitted;
  queue_.erase(me);
  if (!got) throw DeadlineExceeded("time budget exceeded while waiting for a free core");
  return Pass(*this);
}

void ComputeGate::release() {
  const std::lock_guard lock(mutex_);
  for (Waiter& w : queue_)
    if (!w.admitted) {  // the earliest not yet admitted gets the slot
      w.admitted = true;
      w.woken.notify_one();
      return;
    }
  --held_;
}

std::size_t ComputeGate::computing() const {
  const std::lock_guard lock(mutex_);
  return held_;
}

std::size_t ComputeGate::waiting() const {
  const std::lock_guard lock(mutex_);
  std::size_t n = 0;
  for (const Waiter& w : queue_) n += w.admitted ? 0 : 1;
  return n;
}

}  // namespace slamvdb
