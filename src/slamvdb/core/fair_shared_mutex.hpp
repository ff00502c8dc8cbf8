#pragma once
// A reader-writer lock that does not starve writers. std::shared_mutex on glibc prefers readers:
// two threads that read the map back to back (a viewer, a query server) would keep the mapping
// thread from ever taking the lock to add a scan. Here a writer first takes the gate, so readers
// that arrive after it wait until it is done; readers already inside finish first.
#include <mutex>
#include <shared_mutex>

namespace slamvdb {

class FairSharedMutex {
 public:
  void lock() {
    std::lock_guard gate(gate_);
    rw_.lock();
  }
  bool try_lock() {
    std::unique_lock gate(gate_, std::try_to_lock);
    return gate.owns_lock() && rw_.try_lock();
  }
  void unlock() { rw_.unlock(); }
  void lock_shared() {
    { std::lock_guard gate(gate_); }
    rw_.lock_shared();
  }
  bool try_lock_shared() { return rw_.try_lock_shared(); }
  void unlock_shared() { rw_.unlock_shared(); }

 private:
  std::mutex gate_;
  std::shared_mutex rw_;
};

}  // namespace slamvdb
