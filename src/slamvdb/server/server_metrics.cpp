#include "slamvdb/server/server_metrics.hpp"

#include <fmt/format.h>

namespace slamvdb {

void ServerMetrics::record(const std::string& route, int status, double seconds) {
  std::lock_guard lock(mutex_);
  RouteStats& r = routes_[route];
  ++r.by_status[status];
  std::size_t b = 0;
  while (b < kBuckets.size() && seconds > kBuckets[b]) ++b;
  ++r.buckets[b];
  r.sum += seconds;
  ++r.count;
}

void ServerMetrics::record_time_budget_exceeded(const std::string& route) {
  std::lock_guard lock(mutex_);
  ++routes_[route].over_budget;
}

ServerMetrics::InFlight::InFlight(ServerMetrics& m) : metrics(m) {
  std::lock_guard lock(m.mutex_);
  count = ++m.in_flight_;
}

ServerMetrics::InFlight::~InFlight() {
  std::lock_guard lock(metrics.mutex_);
  --metrics.in_flight_;
}

std::string ServerMetrics::text(const std::map<std::string, std::pair<double, std::string>>& gauges) const {
  std::lock_guard lock(mutex_);
  std::string out;
  out += "# HELP slamvdb_http_requests_total Requests answered, by route pattern and HTTP status.\n"
         "# TYPE slamvdb_http_requests_total counter\n";
  for (const auto& [route, r] : routes_)
    for (const auto& [status, n] : r.by_status)
      out += fmt::format("slamvdb_http_requests_total{{route=\"{}\",status=\"{}\"}} {}\n", route, status, n);
  out += "# HELP slamvdb_http_request_seconds Time to answer a request, by route pattern.\n"
         "# TYPE slamvdb_http_request_seconds histogram\n";
  for (const auto& [route, r] : routes_) {
    uint64_t cumulative = 0;
    for (std::size_t b = 0; b < kBuckets.size(); ++b) {
      cumulative += r.buckets[b];
      out += fmt::format("slamvdb_http_request_seconds_bucket{{route=\"{}\",le=\"{}\"}} {}\n", route, kBuckets[b],
                         cumulative);
    }
    out += fmt::format("slamvdb_http_request_seconds_bucket{{route=\"{}\",le=\"+Inf\"}} {}\n", route, r.count);
    out += fmt::format("slamvdb_http_request_seconds_sum{{route=\"{}\"}} {}\n", route, r.sum);
    out += fmt::format("slamvdb_http_request_seconds_count{{route=\"{}\"}} {}\n", route, r.count);
  }
  out += "# HELP slamvdb_http_time_budget_exceeded_total Requests stopped by the time budget (--time-budget), by "
         "route pattern (answered 503).\n# TYPE slamvdb_http_time_budget_exceeded_total counter\n";
  for (const auto& [route, r] : routes_)
    if (r.over_budget)
      out += fmt::format("slamvdb_http_time_budget_exceeded_total{{route=\"{}\"}} {}\n", route, r.over_budget);
  out += fmt::format("# HELP slamvdb_http_requests_in_flight Requests being answered.\n"
                     "# TYPE slamvdb_http_requests_in_flight gauge\nslamvdb_http_requests_in_flight {}\n",
                     in_flight_);
  for (const auto& [name, value] : gauges)
    out += fmt::format("# HELP {} {}\n# TYPE {} gauge\n{} {}\n", name, value.second, name, name, value.first);
  return out;
}

}  // namespace slamvdb
