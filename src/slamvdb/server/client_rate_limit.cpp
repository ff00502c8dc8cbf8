#include "slamvdb/server/client_rate_limit.hpp"

#include <algorithm>
#include <cmath>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

ClientRateLimit::ClientRateLimit(double per_second, double burst, std::size_t max_clients)
    : per_second_(per_second), burst_(burst), max_clients_(std::max<std::size_t>(max_clients, 1)) {
  if (!(per_second > 0) || !std::isfinite(per_second)) throw Error("a client rate limit needs a positive rate");
  if (!(burst >= 1) || !std::isfinite(burst)) throw Error("a client rate limit needs a burst of at least 1");
}

ClientRateLimit::Decision ClientRateLimit::admit(const std::string& client, Clock::time_point now) {
  const std::lock_guard lock(mutex_);
  const auto refilled = [&](const Bucket& b) {
    const double elapsed = std::max(0.0, std::chrono::duration<double>(now - b.at).count());
    return std::min(burst_, b.tokens + elapsed * per_second_);
  };
  if (buckets_.size() >= max_clients_ && !buckets_.contains(client)) {
    std::erase_if(buckets_, [&](const auto& entry) { return refilled(entry.second) >= burst_; });
    if (buckets_.size() >= max_clients_) return {true, 0};
  }
  auto [it, fresh] = buckets_.try_emplace(client, Bucket{burst_, now});
  Bucket& b = it->second;
  if (!fresh) b = {refilled(b), now};
  if (b.tokens >= 1.0) {
    b.tokens -= 1.0;
    return {true, 0};
  }
  return {false, std::max(1, static_cast<int>(std::ceil((1.0 - b.tokens) / per_second_)))};
}

std::size_t ClientRateLimit::clients() const {
  const std::lock_guard lock(mutex_);
  return buckets_.size();
}

}  // namespace slamvdb
