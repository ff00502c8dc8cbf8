// A rate per client address (issue 21, "Security and limits"): ClientRateLimit's token bucket on
// explicit clocks (a burst at once, then the rate; addresses apart; memory bounded), and a real
// `slamvdb serve --rate-limit 2 --rate-burst 3` on loopback: the fourth quick request is refused
// with 429, Retry-After and a message naming the options, /healthz is never refused, and after
// the bucket refills the client is answered again. `--rate-limit 0` turns it off.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "slamvdb/core/error.hpp"
#include "slamvdb/server/client_rate_limit.hpp"
#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

TEST(ClientRateLimit, ABurstAtOnceThenTheRatePerAddressWithBoundedMemory) {
  ClientRateLimit limit(2.0, 3.0, 4);
  const auto t0 = ClientRateLimit::Clock::time_point{} + std::chrono::hours(1);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(limit.admit("10.0.0.1", t0).admitted) << i;
  const auto refused = limit.admit("10.0.0.1", t0);
  EXPECT_FALSE(refused.admitted);
  EXPECT_EQ(refused.retry_after_seconds, 1);           // one token comes back in 0.5 s
  EXPECT_TRUE(limit.admit("10.0.0.2", t0).admitted);   // another address has its own bucket
  EXPECT_TRUE(limit.admit("10.0.0.1", t0 + std::chrono::milliseconds(500)).admitted);
  EXPECT_FALSE(limit.admit("10.0.0.1", t0 + std::chrono::milliseconds(500)).admitted);
  // Never more than the burst, however long the client was idle.
  const auto later = t0 + std::chrono::hours(1);
  for (int i = 0; i < 3; ++i) EXPECT_TRUE(limit.admit("10.0.0.1", later).admitted);
  EXPECT_FALSE(limit.admit("10.0.0.1", later).admitted);
  // Bounded: idle (refilled) addresses are forgotten to make room; busy ones are kept.
  for (int i = 0; i < 10; ++i) limit.admit("10.0.1." + std::to_string(i), later + std::chrono::minutes(1));
  EXPECT_LE(limit.clients(), 4u);
  EXPECT_THROW([] { ClientRateLimit bad(0.0, 3.0); }(), Error);
  EXPECT_THROW([] { ClientRateLimit bad(1.0, 0.5); }(), Error);
}

TEST(ServeRateLimit, AClientOverItsRateGets429WithRetryAfterAndHealthzStillAnswers) {
  testing::TwoClassMap f;
  testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--ignore-model-id", "--rate-limit", "2",
                                 "--rate-burst", "3"},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  for (int i = 0; i < 3; ++i) {
    const auto res = client.Get("/api/info");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << i;
  }
  const auto refused = client.Post("/api/query", R"({"text": "grass", "top_k": 3})", "application/json");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 429) << refused->body;
  EXPECT_EQ(refused->get_header_value("Retry-After"), "1");
  const auto error = nlohmann::json::parse(refused->body).at("error");
  EXPECT_NE(error.at("message").get<std::string>().find("--rate-limit"), std::string::npos) << error;
  for (int i = 0; i < 5; ++i) {  // monitoring is never counted nor refused
    const auto health = client.Get("/healthz");
    ASSERT_TRUE(health);
    EXPECT_EQ(health->status, 200);
  }
  const auto metrics = client.Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("status=\"429\""), std::string::npos) << metrics->body;
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // two tokens back
  const auto again = client.Post("/api/query", R"({"text": "grass", "top_k": 3})", "application/json");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200) << again->body;
  EXPECT_EQ(server.stop(SIGTERM), 0);

  testing::ServerProcess unlimited(SLAMVDB_CLI_PATH,
                                   {"serve", f.map.string(), "--port", "0", "--ignore-model-id", "--rate-limit", "0",
                                    "--rate-burst", "1"},
                                   (f.tmp.path / "serve2.log").string());
  ASSERT_GT(unlimited.port(), 0) << unlimited.output();
  httplib::Client other("127.0.0.1", unlimited.port());
  for (int i = 0; i < 20; ++i) {
    const auto res = other.Get("/api/info");
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 200) << i;
  }
  EXPECT_EQ(unlimited.stop(SIGTERM), 0);
}

}  // namespace
}  // namespace slamvdb
