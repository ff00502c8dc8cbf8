#pragma once
// GET /metrics: Prometheus text format 0.0.4. Requests counted by route pattern (never the raw
// path: labels stay bounded whatever clients send) and status, latency histograms per route, the
// map's size and the text cache's hits. Thread-safe; one short lock per request.
#include <array>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

namespace slamvdb {

class ServerMetrics {
 public:
  // Upper bounds of the latency buckets in seconds (+Inf is implied).
  static constexpr std::array<double, 12> kBuckets = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
                                                      0.1,   0.25,   0.5,   1.0,  2.5,   10.0};
  // `route`: a route's pattern, or "unmatched" for requests no route took.
  void record(const std::string& route, int status, double seconds);
  // A request of `route` stopped by the time budget (--time-budget); also record()ed with its 503.
  void record_time_budget_exceeded(const std::string& route);
  // Requests being answered now (the admission limit reads it).
  struct InFlight {
    explicit InFlight(ServerMetrics& m);
    ~InFlight();
    InFlight(const InFlight&) = delete;
    InFlight& operator=(const InFlight&) = delete;
    std::size_t count;  // including this one
    ServerMetrics& metrics;
  };
  // The request counters and histograms, and `gauges` (name -> value, with their HELP lines from
  // `help`) in the exposition format.
  std::string text(const std::map<std::string, std::pair<double, std::string>>& gauges) const;

 private:
  struct RouteStats {
    std::map<int, uint64_t> by_status;
    std::array<uint64_t, kBuckets.size() + 1> buckets{};  // not cumulative; the last is +Inf
    double sum = 0;
    uint64_t count = 0;
    uint64_t over_budget = 0;
  };
  mutable std::mutex mutex_;
  std::map<std::string, RouteStats> routes_;
  std::size_t in_flight_ = 0;
};

}  // namespace slamvdb
