#pragma once
// For tests of `slamvdb serve`: the two-class map (two_class_map.hpp) served by a child
// `slamvdb serve --port 0` with its query set, a client for it, the CLI's answers on the same
// map, and an answer's rows as the CLI's CSV writes them, so that tests compare the two.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "slamvdb/server/httplib_include.hpp"
#include "slamvdb/testing/csv_reader.hpp"
#include "slamvdb/testing/server_process.hpp"
#include "slamvdb/testing/text_file.hpp"
#include "slamvdb/testing/two_class_map.hpp"

namespace slamvdb::testing {

// An answer's results as the CLI's CSV writes them (query -o X.csv with --queries).
inline std::vector<std::vector<std::string>> query_answer_rows(const nlohmann::json& answer) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& r : answer.at("results")) {
    const auto& p = r.at("position");
    rows.push_back({fmt::format("{}", r.at("rank").get<int>()), fmt::format("{:.3f}", p[0].get<double>()),
                    fmt::format("{:.3f}", p[1].get<double>()), fmt::format("{:.3f}", p[2].get<double>()),
                    fmt::format("{:.6f}", r.at("score").get<float>()), fmt::format("{}", r.at("count").get<uint32_t>()),
                    fmt::format("{:.3f}", r.at("weight").get<float>()),
                    r.at("spread").is_null() ? "" : fmt::format("{:.6f}", r.at("spread").get<float>()),
                    r.at("class").is_null() ? "" : r.at("class").get<std::string>(),
                    fmt::format("{:.4f}", r.at("confidence").get<float>())});
  }
  return rows;
}

// An /api/classes answer's results as `classify -o X.csv` writes them.
inline std::vector<std::vector<std::string>> classes_answer_rows(const nlohmann::json& answer) {
  std::vector<std::vector<std::string>> rows;
  for (const auto& r : answer.at("results")) {
    const auto& p = r.at("position");
    rows.push_back({fmt::format("{:.3f}", p[0].get<double>()), fmt::format("{:.3f}", p[1].get<double>()),
                    fmt::format("{:.3f}", p[2].get<double>()),
                    r.at("class").is_null() ? "" : r.at("class").get<std::string>(),
                    fmt::format("{:.6f}", r.at("score").get<float>()), fmt::format("{:.6f}", r.at("margin").get<float>()),
                    fmt::format("{}", r.at("count").get<uint32_t>()), fmt::format("{:.4f}", r.at("confidence").get<float>())});
  }
  return rows;
}

struct ServedMap {
  testing::TwoClassMap f;
  testing::ServerProcess server{SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(),
                                 "--ignore-model-id", "--max-body", "4096"},
                                (f.tmp.path / "serve.log").string()};
  httplib::Client client{"127.0.0.1", server.port()};

  std::string log() const { return testing::read_text_file(f.tmp.path / "serve.log"); }
  // `slamvdb query MAP ARGS --queries Q --ignore-model-id -o out.csv`: its CSV rows without the header.
  std::vector<std::vector<std::string>> cli_rows(const std::string& args) const {
    const auto out = f.tmp.path / "cli.csv";
    const auto r = run_command(f.cli("query " + shell_quote(f.map.string()) + " " + args + " --queries " +
                                     shell_quote(f.queries.string()) + " --ignore-model-id -o " + shell_quote(out.string())));
    EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
    std::string error;
    auto records = testing::read_csv_strict(testing::read_text_file(out), &error);
    EXPECT_TRUE(records) << error;
    if (!records || records->empty()) return {};
    return {records->begin() + 1, records->end()};
  }
  nlohmann::json post_query(const nlohmann::json& body, int expected_status = 200) {
    const auto res = client.Post("/api/query", body.dump(), "application/json");
    EXPECT_TRUE(res) << "no answer; server log:\n" << log();
    if (!res) return {};
    EXPECT_EQ(res->status, expected_status) << body.dump() << "\n" << res->body;
    EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
    return nlohmann::json::parse(res->body);
  }
};

}  // namespace slamvdb::testing
