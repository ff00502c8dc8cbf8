// `slamvdb serve` against a real server on an ephemeral loopback port: its answers equal the CLI's
// on the same map (query by text, class and vector, with not-terms, top_k and threshold; --at;
// info --json --check), every refusal is a JSON error with the right status and field, a token
// guards the routes, TLS serves, and /metrics counts what was asked.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <array>
#include <fstream>
#include <nlohmann/json.hpp>

#include "slamvdb/io/npy.hpp"
#include "slamvdb/testing/csv_reader.hpp"
#include "slamvdb/testing/served_map.hpp"
#include "slamvdb/testing/text_file.hpp"
#include "slamvdb/server/httplib_include.hpp"

namespace slamvdb {
namespace {

using testing::run_command;
using testing::shell_quote;

using testing::query_answer_rows;
using testing::ServedMap;

TEST(ServeCommand, AnswersEqualTheCli) {
  ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();

  const auto health = s.client.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  const auto h = nlohmann::json::parse(health->body);
  EXPECT_EQ(h.at("status"), "ok");
  EXPECT_EQ(h.at("semantic_cells").get<std::size_t>(), s.f.semantic_cells);
  EXPECT_TRUE(h.at("encoder").at("simulated").get<bool>());  // SIMULATED, said so in every answer

  // /api/info is `info --json --check` of the file, plus the encoder.
  const auto info = s.client.Get("/api/info");
  ASSERT_TRUE(info);
  ASSERT_EQ(info->status, 200);
  auto served_info = nlohmann::json::parse(info->body);
  EXPECT_EQ(served_info.at("encoder"), h.at("encoder"));
  served_info.erase("encoder");
  EXPECT_EQ(served_info.at("served_from"), "file");  // a fleet map says "fleet" (ServeFleet.*)
  served_info.erase("served_from");
  const auto cli_info = run_command(shell_quote(SLAMVDB_CLI_PATH) + " info " + shell_quote(s.f.map.string()) +
                                    " --json --check 2>/dev/null");
  ASSERT_EQ(cli_info.exit_code, 0);
  EXPECT_EQ(served_info, nlohmann::json::parse(cli_info.output));

  // Text (positive and negative), class and vector questions, top_k and threshold: the CLI's rows.
  const float v[4] = {0.8f, 0.3f, 0.1f, 0.f};
  const auto npy = s.f.tmp.path / "v.npy";
  write_npy_array(npy, v, {4});
  const std::vector<std::pair<nlohmann::json, std::string>> cases = {
      {{{"text", "grass"}, {"top_k", 7}}, "--text grass --top-k 7"},
      {{{"text", {"grass", "dirt"}}, {"not", "tree"}, {"top_k", 12}}, "--text grass --text dirt --not tree --top-k 12"},
      {{{"class", "smooth"}, {"not_class", "rough"}, {"top_k", 5}}, "--class smooth --not-class rough --top-k 5"},
      {{{"vector", {0.8, 0.3, 0.1, 0.0}}, {"top_k", 9}}, "--vector " + shell_quote(npy.string()) + " --top-k 9"},
      {{{"class", "rough"}, {"top_k", 0}, {"threshold", 0.5}}, "--class rough --top-k 0 --threshold 0.5"},
  };
  for (const auto& [body, args] : cases) {
    const nlohmann::json answer = s.post_query(body);
    ASSERT_TRUE(answer.contains("results")) << body.dump();
    EXPECT_TRUE(answer.at("encoder").at("simulated").get<bool>());
    const auto expected = s.cli_rows(args);
    ASSERT_FALSE(expected.empty()) << args;
    EXPECT_EQ(query_answer_rows(answer), expected) << body.dump() << " vs " << args;
    EXPECT_EQ(answer.at("count").get<std::size_t>(), expected.size());
  }
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

// /api/at's rows as the CLI's `query --at -o X.csv` writes them (with --queries).
std::vector<std::vector<std::string>> rows_of_at_answer(const nlohmann::json& answer) {
  const auto num = [](const nlohmann::json& v, const char* format) {
    return v.is_null() ? std::string() : fmt::format(fmt::runtime(format), v.get<double>());
  };
  std::vector<std::vector<std::string>> rows;
  for (const auto& r : answer.at("results")) {
    const auto& p = r.at("point");
    const bool found = r.at("found").get<bool>();
    const auto& c = r.at("cell");
    rows.push_back({fmt::format("{}", p[0].get<double>()), fmt::format("{}", p[1].get<double>()),
                    fmt::format("{}", p[2].get<double>()), found ? "1" : "0",
                    found ? fmt::format("{:.3f}", c[0].get<double>()) : "0.000",
                    found ? fmt::format("{:.3f}", c[1].get<double>()) : "0.000",
                    found ? fmt::format("{:.3f}", c[2].get<double>()) : "0.000",
                    fmt::format("{}", r.at("count").get<uint32_t>()),
                    r.at("class").is_null() ? "" : r.at("class").get<std::string>(),
                    num(r.at("score"), "{:.6f}"), num(r.at("margin"), "{:.6f}"), num(r.at("weight"), "{:.3f}"),
                    num(r.at("spread"), "{:.6f}"), num(r.at("confidence"), "{:.4f}"),
                    r.at("last_session").is_null() ? "" : r.at("last_session").get<std::string>()});
  }
  return rows;
}

TEST(ServeCommand, AtAndSubmapsEqualTheCli) {
  ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  // Points on both classes' ground, one in the air (no cell) and one far away.
  const std::vector<std::array<double, 3>> points = {{-2.1, 1.3, 0.05}, {2.6, -0.4, 0.0}, {0.1, 0.1, 3.0}, {100, 100, 100}};
  nlohmann::json body = {{"points", nlohmann::json::array()}};
  std::string at_args;
  for (const auto& p : points) {
    body["points"].push_back({p[0], p[1], p[2]});
    at_args += fmt::format(" --at {},{},{}", p[0], p[1], p[2]);
  }
  const auto res = s.client.Post("/api/at", body.dump(), "application/json");
  ASSERT_TRUE(res) << s.log();
  ASSERT_EQ(res->status, 200) << res->body;
  const auto answer = nlohmann::json::parse(res->body);
  EXPECT_EQ(answer.at("count").get<std::size_t>(), points.size());
  EXPECT_EQ(answer.at("found").get<std::size_t>(), 2u);
  const auto out = s.f.tmp.path / "at.csv";
  const auto r = run_command(s.f.cli("query " + shell_quote(s.f.map.string()) + at_args + " --queries " +
                                     shell_quote(s.f.queries.string()) + " --ignore-model-id -o " + shell_quote(out.string())));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::string error;
  const auto records = testing::read_csv_strict(testing::read_text_file(out), &error);
  ASSERT_TRUE(records) << error;
  EXPECT_EQ(rows_of_at_answer(answer), std::vector<std::vector<std::string>>(records->begin() + 1, records->end()));
  // With embeddings: the cell's mean (class 0's e0 at x < 0), nothing where no cell is.
  body["embedding"] = true;
  const auto with = s.client.Post("/api/at", body.dump(), "application/json");
  ASSERT_TRUE(with);
  const auto e = nlohmann::json::parse(with->body).at("results");
  EXPECT_NEAR(e[0].at("embedding")[0].get<double>(), 1.0, 1e-3);
  EXPECT_TRUE(e[2].at("embedding").is_null());

  // /api/submaps: what info --json says of each submap.
  const auto submaps = s.client.Get("/api/submaps");
  ASSERT_TRUE(submaps);
  ASSERT_EQ(submaps->status, 200);
  const auto cli_info = run_command(shell_quote(SLAMVDB_CLI_PATH) + " info " + shell_quote(s.f.map.string()) +
                                    " --json 2>/dev/null");
  ASSERT_EQ(cli_info.exit_code, 0);
  EXPECT_EQ(nlohmann::json::parse(submaps->body).at("submaps"), nlohmann::json::parse(cli_info.output).at("submaps"));
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

TEST(ServeCommand, RefusalsAreJsonErrorsNamingTheField) {
  ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const auto expect_error = [&](const httplib::Result& res, int status, const nlohmann::json& field) {
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, status) << res->body;
    const auto j = nlohmann::json::parse(res->body, nullptr, false);
    ASSERT_TRUE(j.is_object() && j.contains("error")) << res->body;
    EXPECT_FALSE(j["error"].at("message").get<std::string>().empty());
    EXPECT_EQ(j["error"].at("field"), field) << res->body;
  };
  const auto post = [&](const std::string& body) { return s.client.Post("/api/query", body, "application/json"); };
  expect_error(post("{\"text\": "), 400, nullptr);                       // not JSON
  expect_error(post("[1, 2]"), 400, nullptr);                            // not an object
  expect_error(post(std::string(20, '[') + std::string(20, ']')), 400, nullptr);  // too deep
  expect_error(post(R"({"txt": "grass"})"), 400, "txt");                 // unknown field
  expect_error(post(R"({"text": "grass", "top_k": -1})"), 400, "top_k");
  expect_error(post(R"({"text": "grass", "top_k": 0})"), 400, "top_k");  // 0 needs a threshold
  expect_error(post(R"({"text": "grass", "threshold": 2})"), 400, "threshold");
  expect_error(post(R"({"text": 5})"), 400, "text");
  expect_error(post(R"({"text": "no such words"})"), 400, "text");       // the encoder knows no class in it
  expect_error(post(R"({"class": "gravel"})"), 400, "class");            // not in the query set
  expect_error(post(R"({"vector": [1, 2]})"), 400, "vector");            // the map's embeddings are 4-d
  expect_error(post(R"({"not": "grass"})"), 400, "text");                // no positive term
  expect_error(post(R"({"vector": [1, 0, 0, 0], "not_vector": [1, 0, 0, 0]})"), 400, "vector");  // cancel out
  expect_error(post("{\"text\": \"" + std::string(5000, 'a') + "\"}"), 413, "body");  // --max-body 4096
  const auto post_at = [&](const std::string& body) { return s.client.Post("/api/at", body, "application/json"); };
  expect_error(post_at(R"({"points": []})"), 400, "points");
  expect_error(post_at(R"({"points": [[1, 2]]})"), 400, "points");
  expect_error(post_at(R"({"points": [[1, 2, 3]], "embedding": "yes"})"), 400, "embedding");
  expect_error(post_at(R"({"point": [[1, 2, 3]]})"), 400, "point");
  expect_error(s.client.Get("/api/nothing"), 404, nullptr);
  expect_error(s.client.Get("/api/query"), 405, nullptr);
  expect_error(s.client.Delete("/api/info"), 405, nullptr);
  // Still serving after every refusal.
  const auto health = s.client.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

TEST(ServeCommand, RefusesNonLoopbackAddressesWithoutAuthentication) {
  const testing::TwoClassMap f;
  const auto r = run_command(f.cli("serve " + shell_quote(f.map.string()) + " --bind 0.0.0.0 --port 0"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--bind 0.0.0.0: another address than loopback needs --token FILE"), std::string::npos)
      << r.output;
  // A short token is refused before the map is served.
  const auto token = f.tmp.path / "short.token";
  std::ofstream(token) << "secret\n";
  const auto t = run_command(f.cli("serve " + shell_quote(f.map.string()) + " --port 0 --token " + shell_quote(token.string())));
  EXPECT_EQ(t.exit_code, 1) << t.output;
  EXPECT_NE(t.output.find("use at least 16"), std::string::npos) << t.output;
}

TEST(ServeCommand, TokenGuardsEveryRouteButHealthz) {
  testing::TwoClassMap f;
  const auto token_file = f.tmp.path / "serve.token";
  const std::string token = "0123456789abcdef-token";
  std::ofstream(token_file) << "  " << token << "  \nsecond line ignored\n";
  testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--ignore-model-id", "--token", token_file.string()},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  const auto health = client.Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  for (const std::string& bad :
       std::vector<std::string>{"", "Bearer wrong", "Bearer " + token + "x", "Basic " + token, token}) {
    httplib::Headers headers;
    if (!bad.empty()) headers.emplace("Authorization", bad);
    const auto res = client.Get("/api/info", headers);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 401) << bad;
    EXPECT_EQ(res->get_header_value("WWW-Authenticate"), "Bearer");
    EXPECT_TRUE(nlohmann::json::parse(res->body).at("error").contains("message"));
    const auto query = client.Post("/api/query", headers, R"({"text": "grass"})", "application/json");
    ASSERT_TRUE(query);
    EXPECT_EQ(query->status, 401) << bad;
  }
  const httplib::Headers good = {{"Authorization", "Bearer " + token}};
  const auto info = client.Get("/api/info", good);
  ASSERT_TRUE(info);
  EXPECT_EQ(info->status, 200);
  const auto query = client.Post("/api/query", good, R"({"text": "grass", "top_k": 3})", "application/json");
  ASSERT_TRUE(query);
  EXPECT_EQ(query->status, 200) << query->body;
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

TEST(ServeCommand, ServesHttpsWithACertificateAndItsKey) {
  testing::TwoClassMap f;
  const auto cert = f.tmp.path / "cert.pem", key = f.tmp.path / "key.pem", other_key = f.tmp.path / "other.pem";
  // A self-signed pair made by the openssl command (Debian's openssl package).
  const auto made = run_command("openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 1 "
                                "-subj /CN=127.0.0.1 -keyout " + shell_quote(key.string()) + " -out " +
                                shell_quote(cert.string()) + " 2>&1 && openssl genpkey -algorithm EC -pkeyopt "
                                "ec_paramgen_curve:prime256v1 -out " + shell_quote(other_key.string()) + " 2>&1");
  ASSERT_EQ(made.exit_code, 0) << made.output;
  {
    testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                  {"serve", f.map.string(), "--port", "0", "--ignore-model-id", "--tls-cert",
                                   cert.string(), "--tls-key", key.string()},
                                  (f.tmp.path / "serve.log").string());
    ASSERT_GT(server.port(), 0) << server.output();
    EXPECT_NE(server.output().find("https://127.0.0.1:"), std::string::npos) << server.output();
    httplib::SSLClient client("127.0.0.1", server.port());
    client.enable_server_certificate_verification(false);  // self-signed: TLS is what is tested, not a CA
    const auto res = client.Post("/api/query", R"({"text": "grass", "top_k": 2})", "application/json");
    ASSERT_TRUE(res) << httplib::to_string(res.error());
    EXPECT_EQ(res->status, 200) << res->body;
    EXPECT_EQ(nlohmann::json::parse(res->body).at("count").get<int>(), 2);
    // Plain HTTP to the TLS port gets no answer.
    httplib::Client plain("127.0.0.1", server.port());
    plain.set_read_timeout(2, 0);
    const auto p = plain.Get("/healthz");
    EXPECT_FALSE(p && p->status == 200);
    EXPECT_EQ(server.stop(SIGTERM), 0);
  }
  // A key that is not the certificate's: an error naming both files, before serving.
  const auto r = run_command(f.cli("serve " + shell_quote(f.map.string()) + " --port 0 --ignore-model-id --tls-cert " +
                                   shell_quote(cert.string()) + " --tls-key " + shell_quote(other_key.string())));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cannot use the TLS certificate"), std::string::npos) << r.output;
  // One without the other: a usage error.
  const auto half = run_command(f.cli("serve " + shell_quote(f.map.string()) + " --tls-cert " + shell_quote(cert.string())));
  EXPECT_EQ(half.exit_code, 2) << half.output;
}

// The Prometheus counter of `route` and `status` in `text`, -1 when absent.
long counter(const std::string& text, const std::string& route, int status) {
  const std::string key = fmt::format("slamvdb_http_requests_total{{route=\"{}\",status=\"{}\"}} ", route, status);
  const auto at = text.find(key);
  return at == std::string::npos ? -1 : std::atol(text.c_str() + at + key.size());
}

TEST(ServeCommand, MetricsCountRequestsByRouteAndStatus) {
  ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  for (int i = 0; i < 3; ++i) s.post_query({{"text", "grass"}, {"top_k", 2}});
  s.post_query({{"text", "grass"}, {"top_k", -2}}, 400);
  ASSERT_TRUE(s.client.Get("/api/nothing/at/all"));
  ASSERT_TRUE(s.client.Get("/api/query"));
  const auto res = s.client.Get("/metrics");
  ASSERT_TRUE(res);
  ASSERT_EQ(res->status, 200);
  EXPECT_EQ(res->get_header_value("Content-Type").rfind("text/plain; version=0.0.4", 0), 0u);
  const std::string& m = res->body;
  EXPECT_EQ(counter(m, "/api/query", 200), 3) << m;
  EXPECT_EQ(counter(m, "/api/query", 400), 1) << m;
  EXPECT_EQ(counter(m, "/api/query", 405), 1) << m;
  EXPECT_EQ(counter(m, "unmatched", 404), 1) << m;  // by pattern, never the raw path
  EXPECT_EQ(m.find("/api/nothing"), std::string::npos);
  EXPECT_NE(m.find("slamvdb_http_request_seconds_bucket{route=\"/api/query\",le=\"+Inf\"} 5"), std::string::npos) << m;
  EXPECT_NE(m.find(fmt::format("slamvdb_map_semantic_cells {}", s.f.semantic_cells)), std::string::npos) << m;
  EXPECT_NE(m.find("slamvdb_map_submaps 1"), std::string::npos) << m;
  // Three queries of one text: one encode, two cache hits.
  EXPECT_NE(m.find("slamvdb_text_cache_misses 1\n"), std::string::npos) << m;
  EXPECT_NE(m.find("slamvdb_text_cache_hits 2\n"), std::string::npos) << m;  // the 400 one is refused before
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

}  // namespace
}  // namespace slamvdb
