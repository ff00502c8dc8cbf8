#pragma once
// A request rate per client for `slamvdb serve` (issue 21, "Security and limits"): a token bucket
// per remote address. A client may send `burst` requests at once and `per_second` on average; a
// request beyond that is refused (429 with Retry-After) before any work is done for it. Memory
// stays bounded: when more than `max_clients` addresses are tracked, those whose bucket has
// refilled (idle long enough to be forgotten without changing any answer) are dropped; if all of
// them are busy, a new address is admitted untracked (the --max-concurrent limit still holds).
#include <chrono>
#include <mutex>
#include <string>
#include <unordered_map>

namespace slamvdb {

class ClientRateLimit {
 public:
  using Clock = std::chrono::steady_clock;
  ClientRateLimit(double per_second, double burst, std::size_t max_clients = 65536);
  // Whether `client` may be answered now (taking one token); if not, the whole seconds until it may
  // (for Retry-After, at least 1).
  struct Decision {
    bool admitted = true;
    int retry_after_seconds = 0;
  };
  Decision admit(const std::string& client, Clock::time_point now = Clock::now());
  std::size_t clients() const;
  double per_second() const { return per_second_; }
  double burst() const { return burst_; }

 private:
  struct Bucket {
    double tokens;
    Clock::time_point at;
  };
  double per_second_, burst_;
  std::size_t max_clients_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, Bucket> buckets_;
};

}  // namespace slamvdb
