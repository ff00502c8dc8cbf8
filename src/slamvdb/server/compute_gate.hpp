#pragma once
// At most `slots` answers computing at once, the others waiting their turn in arrival order
// (issue 21, "Speed": 32 clients on 2 cores). httplib gives every admitted request a thread of its
// own (--max-concurrent of them), so without a gate 32 answers share 2 cores at once: each answer's
// memory stream evicts the others' from the caches, and the scheduler's unfair slices stretch the
// slowest answers (p99) far beyond the median. With a gate each answer computes alone on a core,
// and waits in FIFO order, so the time a request waits is the work queued ahead of it.
// --max-concurrent still bounds how many requests may wait (and refuses more with 503).
#include <condition_variable>
#include <cstddef>
#include <list>
#include <mutex>

#include "slamvdb/core/deadline.hpp"

namespace slamvdb {

class ComputeGate {
 public:
  // slots: answers computing at once (0: the machine's hardware threads).
  explicit ComputeGate(std::size_t slots);
  ComputeGate(const ComputeGate&) = delete;
  ComputeGate& operator=(const ComputeGate&) = delete;

  // Holds a slot until destroyed.
  class Pass {
   public:
    explicit Pass(ComputeGate& gate) : gate_(&gate) {}
    Pass(Pass&& other) noexcept : gate_(other.gate_) { other.gate_ = nullptr; }
    Pass& operator=(Pass&&) = delete;
    ~Pass() {
      if (gate_) gate_->release();
    }

   private:
    ComputeGate* gate_;
  };
  // Waits for a slot behind everyone who came earlier. Throws DeadlineExceeded (and leaves the
  // queue) when `deadline` passes first.
  Pass enter(const Deadline& deadline = {});

  std::size_t slots() const { return slots_; }
  std::size_t computing() const;  // slots held now
  std::size_t waiting() const;    // requests queued for a slot now

 private:
  struct Waiter {
    std::condition_variable woken;
    bool admitted = false;
  };
  void release();

  std::size_t slots_;
  mutable std::mutex mutex_;
  std::size_t held_ = 0;
  std::list<Waiter> queue_;  // front: the earliest; a waiter is admitted by the slot's releaser
};

}  // namespace slamvdb
