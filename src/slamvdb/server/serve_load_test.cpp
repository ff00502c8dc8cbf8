// A bounded load on a served map: many client threads over loopback, a fixed count of requests
// each, mixing the routes (query by class, at, classes, nav-grid), more clients than
// --max-concurrent (queries computed one at a time: --compute-slots 1). Every answer is a 200 or
// the documented 503 (with Retry-After), never another status or a dropped connection; the server
// answers /healthz afterwards, shows no query slot held, and stops cleanly.
// Latency p50/p99 is printed (bench/bench_serve.cpp measures it on a million cells). No connection
// overflowed the listen backlog (the kernel's count; such a client waits 1 s for its SYN's resend).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <mutex>
#include <thread>

#include "slamvdb/testing/client_load.hpp"
#include "slamvdb/testing/served_map.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb {
namespace {

// The kernel's count of connections dropped because a listen backlog was full (TcpExt
// ListenOverflows in /proc/net/netstat, for the whole machine); -1 where it cannot be read.
long long listen_overflows() {
  std::ifstream netstat("/proc/net/netstat");
  std::string names, values;
  while (std::getline(netstat, names) && std::getline(netstat, values)) {
    if (names.rfind("TcpExt:", 0) != 0) continue;
    std::istringstream n(names), v(values);
    for (std::string name, value; n >> name && v >> value;)
      if (name == "ListenOverflows") return std::stoll(value);
  }
  return -1;
}

TEST(ServeLoad, ManyClientsGetAnswersOr503AndNothingElse) {
  testing::TwoClassMap f;
  testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(),
                                 "--ignore-model-id", "--max-concurrent", "4", "--compute-slots", "1"},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  constexpr int kClients = 16, kRequests = 12;
  const long long overflows_before = listen_overflows();
  std::mutex m;
  std::vector<double> latencies_ms;
  std::map<int, int> statuses;  // -1: no answer
  int refused_without_retry_after = 0;
  std::vector<std::thread> threads;
  for (int c = 0; c < kClients; ++c)
    threads.emplace_back([&, c] {
      httplib::Client client("127.0.0.1", server.port());
      client.set_read_timeout(60, 0);
      for (int r = 0; r < kRequests; ++r) {
        const int kind = (c + r) % 4;
        const auto t0 = std::chrono::steady_clock::now();
        httplib::Result res =
            kind == 0   ? client.Post("/api/query", fmt::format(R"({{"class": "{}", "top_k": {}}})", r % 2 ? "smooth" : "rough", 1 + r),
                                      "application/json")
            : kind == 1 ? client.Post("/api/at", fmt::format(R"({{"points": [[{}, 0.3, 0], [-1, -1, 0]]}})", 0.1 * r),
                                      "application/json")
            : kind == 2 ? client.Get(fmt::format("/api/classes?bbox=-2,-2,-1,{},2,1", 0.5 + 0.1 * r))
                        : client.Get(fmt::format("/api/nav-grid?near=0,0&radius={}", 1.0 + 0.1 * r));
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        const std::lock_guard lock(m);
        latencies_ms.push_back(ms);
        ++statuses[res ? res->status : -1];
        if (res && res->status == 503 && res->get_header_value("Retry-After").empty()) ++refused_without_retry_after;
      }
    });
  for (std::thread& t : threads) t.join();
  std::sort(latencies_ms.begin(), latencies_ms.end());
  ASSERT_EQ(latencies_ms.size(), static_cast<std::size_t>(kClients * kRequests));
  fmt::print("{} requests from {} clients (--max-concurrent 4): {} answered 200, {} refused 503; p50 {:.1f} ms, p99 "
             "{:.1f} ms\n",
             latencies_ms.size(), kClients, statuses[200], statuses[503], latencies_ms[latencies_ms.size() / 2],
             latencies_ms[latencies_ms.size() * 99 / 100]);
  for (const auto& [status, n] : statuses) EXPECT_TRUE(status == 200 || status == 503) << n << " answers with " << status;
  // No client waited for a SYN retransmission (1 s): the listen backlog holds 16 clients
  // connecting at once (httplib's own is 5; MapServer::bind raises it). Counted by the kernel, not
  // timed: a p99 bound of 1 s failed on a loaded machine (1005 ms at a load average of 10) without
  // any overflow. Another program's overflow at the same time would fail it too (none in CI).
  if (overflows_before >= 0) {
    EXPECT_EQ(listen_overflows() - overflows_before, 0);
  }
  EXPECT_GT(statuses[200], 0);
  EXPECT_EQ(refused_without_retry_after, 0);
  httplib::Client client("127.0.0.1", server.port());
  const auto health = client.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  // --compute-slots reached the server, and every query's slot was given back (none computing or
  // waiting once the clients are done).
  const auto metrics = client.Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("\nslamvdb_query_compute_slots 1\n"), std::string::npos) << metrics->body;
  EXPECT_NE(metrics->body.find("\nslamvdb_query_computing 0\n"), std::string::npos) << metrics->body;
  EXPECT_NE(metrics->body.find("\nslamvdb_query_waiting 0\n"), std::string::npos) << metrics->body;
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

// Every file beside the map (the map and any side file a reader might leave: -journal, -wal,
// -shm), by name, with its bytes; the server's log left out.
std::map<std::string, std::string> files_beside(const testing::TwoClassMap& f) {
  std::map<std::string, std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(f.tmp.path))
    if (entry.path().filename() != "serve.log") files[entry.path().filename().string()] = testing::read_text_file(entry.path());
  return files;
}

// Issue 21: a server killed with kill -9 while clients ask (queries, points, at) leaves the map file
// byte-identical, with no side file, and the file still opens (info --check reads every submap).
TEST(ServeLoad, KilledUnderLoadLeavesTheMapFileByteIdentical) {
  testing::TwoClassMap f;
  const std::map<std::string, std::string> before = files_beside(f);
  ASSERT_TRUE(before.count("m.svdb"));
  testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(),
                                 "--ignore-model-id"},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  testing::ClientLoad load(server.port(), 4,
                           {{"/api/query", R"({"class": "smooth", "top_k": 5})"},
                            {"/api/points?lod=0", ""},
                            {"/api/at", R"({"points": [[0.3, 0.3, 0], [-1, -1, 0]]})"},
                            {"/api/query", R"({"class": "rough", "threshold": 0.5})"}});
  // Under load for a moment (about 1 s in Release, 0.5 s under the sanitizers), answered all along.
  const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(testing::test_size(1000, 500));
  while (std::chrono::steady_clock::now() < until || load.answered() < 8)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(server.stop(SIGKILL), -SIGKILL);
  const std::map<int, int> statuses = load.stop();
  for (const auto& [status, n] : statuses)  // 429: the rate limit per client address, shared here
    EXPECT_TRUE(status == 200 || status == 429 || status == 503 || status == -1) << n << " x " << status;
  fmt::print("served {} answers before the kill\n", statuses.count(200) ? statuses.at(200) : 0);

  const std::map<std::string, std::string> after = files_beside(f);
  EXPECT_EQ(after.size(), before.size());
  for (const auto& [name, bytes] : after) {
    ASSERT_TRUE(before.count(name)) << name << " appeared";
    EXPECT_TRUE(bytes == before.at(name)) << name << " changed";
  }
  const auto check = testing::run_command(f.cli("info --check " + f.out("m.svdb")));
  EXPECT_EQ(check.exit_code, 0) << check.output;
}

}  // namespace
}  // namespace slamvdb
