#pragma once
// For tests of `slamvdb serve` and `map|slam --serve`: a few loopback clients sending a fixed mix
// of requests in turn until stop(), each answer counted by its status (-1: no answer, e.g. the
// server was killed). The kill tests (issue 21: "a server killed with kill -9 under load leaves
// every map file byte-identical") kill the server while these still send.
#include <atomic>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "slamvdb/server/httplib_include.hpp"

namespace slamvdb::testing {

struct LoopbackRequest {
  std::string path;
  std::string json_body;  // empty: GET, else POST with this body
};

class ClientLoad {
 public:
  // Client c starts at request c of the mix, so that different routes run at the same time.
  ClientLoad(int port, int clients, std::vector<LoopbackRequest> mix) : mix_(std::move(mix)) {
    for (int c = 0; c < clients; ++c)
      threads_.emplace_back([this, port, c] {
        httplib::Client client("127.0.0.1", port);
        client.set_connection_timeout(2, 0);
        client.set_read_timeout(10, 0);
        for (std::size_t i = static_cast<std::size_t>(c); !stop_; ++i) {
          const LoopbackRequest& r = mix_[i % mix_.size()];
          const httplib::Result res =
              r.json_body.empty() ? client.Get(r.path) : client.Post(r.path, r.json_body, "application/json");
          const int status = res ? res->status : -1;
          if (status == 200) ++answered_;
          const std::lock_guard lock(mutex_);
          ++statuses_[status];
        }
      });
  }
  ~ClientLoad() { stop(); }
  ClientLoad(const ClientLoad&) = delete;
  ClientLoad& operator=(const ClientLoad&) = delete;

  int answered() const { return answered_; }  // 200s so far
  // Ends every client (each after its request in flight) and returns the answers by status.
  std::map<int, int> stop() {
    stop_ = true;
    for (std::thread& t : threads_)
      if (t.joinable()) t.join();
    const std::lock_guard lock(mutex_);
    return statuses_;
  }

 private:
  const std::vector<LoopbackRequest> mix_;
  std::atomic<bool> stop_{false};
  std::atomic<int> answered_{0};
  std::mutex mutex_;
  std::map<int, int> statuses_;
  std::vector<std::thread> threads_;
};

}  // namespace slamvdb::testing
