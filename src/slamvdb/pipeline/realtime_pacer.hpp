#pragma once
// Real-time replay (`map --realtime`, `slam --realtime`): frames are handed on at their stamps on
// the wall clock, as the sensors would deliver them, so that a run shows whether this machine keeps
// up. One clock for the whole replay: stamp t is due at start + (t - first_stamp).
#include <chrono>
#include <functional>

namespace slamvdb {

class RealtimePacer {
 public:
  using Clock = std::chrono::steady_clock;
  // The wall clock; tests give a simulated one (a time they advance themselves).
  struct WallClock {
    std::function<Clock::time_point()> now;
    std::function<void(Clock::time_point)> sleep_until;
  };
  static WallClock steady_clock();

  // first_stamp is due now.
  explicit RealtimePacer(double first_stamp, WallClock clock = steady_clock());

  // Returns once `stamp` is due (at once if it is already).
  void wait_for(double stamp) const;
  // Whether `stamp` has come: a frame of this stamp would have been delivered by now.
  bool arrived(double stamp) const;
  // Seconds since the first stamp was due (the replay's wall time).
  double elapsed() const;
  double first_stamp() const { return first_stamp_; }
  // Every stamp falls due `pause` later (the replay was held: `map --serve-wait-viewer`), so that
  // frames after a hold come at sensor rate again instead of all at once, and elapsed() leaves the
  // hold out.
  void postpone(Clock::duration pause) { start_ += pause; }

 private:
  Clock::time_point due(double stamp) const;

  WallClock clock_;
  double first_stamp_;
  Clock::time_point start_;
};

}  // namespace slamvdb
