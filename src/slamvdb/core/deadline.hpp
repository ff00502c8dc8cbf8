#pragma once
// A time by which a piece of work must end (`slamvdb serve --time-budget`): long loops check it
// between chunks and stop by throwing DeadlineExceeded, so an answer that would take too long ends
// on the thread that computes it instead of being abandoned to a thread that keeps working. Inside
// a TBB loop the throw cancels the remaining chunks and reaches the caller.
#include <chrono>
#include <optional>
#include <string>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

class DeadlineExceeded : public Error {
 public:
  using Error::Error;
};

class Deadline {
 public:
  using Clock = std::chrono::steady_clock;
  Deadline() = default;  // never passes
  explicit Deadline(Clock::time_point at) : at_(at) {}
  // `budget` from now; a zero budget means no deadline.
  static Deadline after(std::chrono::microseconds budget) {
    return budget.count() > 0 ? Deadline(Clock::now() + budget) : Deadline();
  }
  bool set() const { return at_.has_value(); }
  Clock::time_point at() const { return at_.value_or(Clock::time_point::max()); }  // max: never
  bool passed() const { return at_ && Clock::now() >= *at_; }
  // Throws DeadlineExceeded naming `what` (the work being stopped) when the deadline has passed.
  void check(const char* what) const {
    if (passed()) throw DeadlineExceeded(std::string("time budget exceeded while ") + what);
  }

 private:
  std::optional<Clock::time_point> at_;
};

}  // namespace slamvdb
