// GET /api/classes and `slamvdb classify --bbox`: the same rows on the same map (both answer
// through classify_region and the rows of query/class_summary.hpp), those rows are the whole map's
// rows whose cell lies in the box, the summary counts the rows, and refusals name what is wrong
// (400 naming `bbox`, a server without --queries saying so; exit 2 naming the option).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>

#include "slamvdb/core/point_text.hpp"
#include "slamvdb/query/query_region.hpp"
#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

using testing::run_command;
using testing::shell_quote;

using Rows = std::vector<std::vector<std::string>>;
using testing::classes_answer_rows;

// `slamvdb classify MAP --queries Q --ignore-model-id ARGS -o out.csv`: its rows without the header.
Rows classify_cli_rows(const testing::ServedMap& s, const std::string& args) {
  const auto out = s.f.tmp.path / "classes.csv";
  const auto r = run_command(s.f.cli("classify " + shell_quote(s.f.map.string()) + " --queries " +
                                     shell_quote(s.f.queries.string()) + " --ignore-model-id " + args + " -o " +
                                     shell_quote(out.string())));
  EXPECT_EQ(r.exit_code, 0) << args << "\n" << r.output;
  std::string error;
  auto records = testing::read_csv_strict(testing::read_text_file(out), &error);
  EXPECT_TRUE(records) << error;
  if (!records || records->empty()) return {};
  EXPECT_EQ((*records)[0], (std::vector<std::string>{"x", "y", "z", "class", "score", "margin", "count", "confidence",
                                                      "last_session"}));
  Rows rows(records->begin() + 1, records->end());
  for (auto& row : rows) row.pop_back();  // last_session: /api/classes does not answer it (yet)
  return rows;
}

nlohmann::json get_json(testing::ServedMap& s, const std::string& path, int expected_status) {
  const auto res = s.client.Get(path);
  EXPECT_TRUE(res) << "no answer; server log:\n" << s.log();
  if (!res) return {};
  EXPECT_EQ(res->status, expected_status) << path << "\n" << res->body;
  EXPECT_EQ(res->get_header_value("Content-Type"), "application/json");
  return nlohmann::json::parse(res->body);
}

TEST(ServeClasses, RowsEqualClassifyBboxAndAreTheWholeMapsRowsInTheBox) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const Rows whole = classify_cli_rows(s, "");
  ASSERT_GT(whole.size(), 10u);
  for (const auto& [bbox, min_confidence] : std::vector<std::pair<std::string, std::string>>{
           {"-1.1,-0.9,-1,1.3,1.05,1", ""}, {"-3,-2,-1,0.5,2,1", "0.5"}}) {
    const std::string query = "bbox=" + bbox + (min_confidence.empty() ? "" : "&min_confidence=" + min_confidence);
    const nlohmann::json answer = get_json(s, "/api/classes?" + query, 200);
    const Rows rows = classes_answer_rows(answer);
    ASSERT_FALSE(rows.empty()) << query;
    EXPECT_LT(rows.size(), whole.size()) << query;
    EXPECT_EQ(answer.at("count").get<std::size_t>(), rows.size());
    // The CLI's rows for the same box (and threshold).
    const std::string cli_args =
        "--bbox=" + bbox + (min_confidence.empty() ? "" : " --min-confidence " + min_confidence);
    EXPECT_EQ(rows, classify_cli_rows(s, cli_args)) << cli_args;
    // The whole map's rows (same threshold) whose centre is in the box, in the same order.
    const std::vector<double> box = parse_numbers(bbox, "bbox", 6, 6, "box");
    const QueryRegion region = make_region(std::span<const double>(box), {}, {});
    Rows expected;
    for (const auto& row : classify_cli_rows(s, min_confidence.empty() ? "" : "--min-confidence " + min_confidence))
      if (region.contains({std::stod(row[0]), std::stod(row[1]), std::stod(row[2])})) expected.push_back(row);
    EXPECT_EQ(rows, expected) << query;
    // The summary counts the rows: per class, uncertain, none.
    std::map<std::string, std::size_t> by_class;
    for (const auto& row : rows) ++by_class[row[3]];
    for (const auto& c : answer.at("classes"))
      EXPECT_EQ(c.at("voxels").get<std::size_t>(), by_class[c.at("name").get<std::string>()]) << c.dump();
    EXPECT_EQ(answer.at("uncertain").get<std::size_t>(), by_class["uncertain"]);
    EXPECT_EQ(answer.at("unclassified").get<std::size_t>(), by_class[""]);
    EXPECT_EQ(answer.at("region").at("bbox").size(), 6u);
  }
  // near + radius (a vertical cylinder, and a ball): the CLI's rows for the same region.
  for (const std::string near : {"near=0.2,0.1&radius=1.5", "near=0.2,0.1,0&radius=1.2"}) {
    const nlohmann::json answer = get_json(s, "/api/classes?" + near, 200);
    const Rows rows = classes_answer_rows(answer);
    ASSERT_FALSE(rows.empty()) << near;
    EXPECT_LT(rows.size(), whole.size()) << near;
    const auto amp = near.find('&');
    const std::string cli_args = "--near " + near.substr(5, amp - 5) + " --radius " + near.substr(amp + 8);
    EXPECT_EQ(rows, classify_cli_rows(s, cli_args)) << cli_args;
    EXPECT_TRUE(answer.at("region").contains("near")) << answer.at("region").dump();
  }
  // A box outside the map: no rows, not an error.
  const nlohmann::json nowhere = get_json(s, "/api/classes?bbox=100,100,0,110,110,1", 200);
  EXPECT_EQ(nowhere.at("count").get<std::size_t>(), 0u);
  EXPECT_TRUE(nowhere.at("results").empty());

  // Refusals: 400 naming the parameter.
  for (const auto& [query, field] : std::vector<std::pair<std::string, std::string>>{
           {"", "bbox"},
           {"?near=0,0", "radius"},
           {"?radius=2", "near"},
           {"?near=0,0&radius=-1", "radius"},
           {"?near=0&radius=1", "near"},
           {"?bbox=0,0,0,1,1", "bbox"},
           {"?bbox=0,0,3,1,1,1", "bbox"},
           {"?bbox=0,0,0,1,1,nan", "bbox"},
           {"?bbox=0,0,0,1,1,1&min_confidence=2", "min_confidence"},
           {"?bbox=0,0,0,1,1,1&bbx=1", "bbx"}}) {
    const nlohmann::json refusal = get_json(s, "/api/classes" + query, 400);
    EXPECT_EQ(refusal.at("error").at("field"), field) << query;
  }
  for (const auto& [args, option] : std::vector<std::pair<std::string, std::string>>{
           {"--bbox 0,0,0,1,1", "--bbox"},
           {"--bbox 0,0,3,1,1,1", "--bbox: the z minimum 3 is above the maximum 1"},
           {"--near 0,0", "--radius"}}) {
    const auto r = run_command(s.f.cli("classify " + shell_quote(s.f.map.string()) + " --queries " +
                                       shell_quote(s.f.queries.string()) + " --ignore-model-id " + args));
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(option), std::string::npos) << args << "\n" << r.output;
  }
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

// --max-cells: a region holding more cells than the limit is refused with 413 naming both counts
// (the count is the number of rows the region answers without the limit); at the limit it answers.
TEST(ServeClasses, ARegionOverMaxCellsIsRefusedWith413NamingTheCountAndTheLimit) {
  testing::TwoClassMap f;
  const std::string box = "-1.1,-0.9,-1,1.3,1.05,1";
  std::size_t in_box = 0;
  {
    testing::ServerProcess unlimited(SLAMVDB_CLI_PATH,
                                     {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(),
                                      "--ignore-model-id"},
                                     (f.tmp.path / "serve0.log").string());
    ASSERT_GT(unlimited.port(), 0) << unlimited.output();
    httplib::Client client("127.0.0.1", unlimited.port());
    const auto res = client.Get("/api/classes?bbox=" + box);
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200) << res->body;
    in_box = nlohmann::json::parse(res->body).at("count").get<std::size_t>();
    EXPECT_EQ(unlimited.stop(SIGTERM), 0);
  }
  ASSERT_GT(in_box, 2u);
  const std::string limit = std::to_string(in_box - 1);
  testing::ServerProcess server(SLAMVDB_CLI_PATH,
                                {"serve", f.map.string(), "--port", "0", "--queries", f.queries.string(),
                                 "--ignore-model-id", "--max-cells", limit},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  const auto over = client.Get("/api/classes?bbox=" + box);
  ASSERT_TRUE(over);
  EXPECT_EQ(over->status, 413) << over->body;
  const nlohmann::json refusal = nlohmann::json::parse(over->body);
  const std::string message = refusal.at("error").at("message").get<std::string>();
  EXPECT_EQ(refusal.at("error").at("field"), "bbox");
  EXPECT_NE(message.find(std::to_string(in_box) + " semantic cells"), std::string::npos) << message;
  EXPECT_NE(message.find("at most " + limit), std::string::npos) << message;
  EXPECT_NE(message.find("--max-cells"), std::string::npos) << message;
  // A region at or under the limit answers (a smaller box: part of the cells).
  const auto under = client.Get("/api/classes?bbox=-1.1,-0.9,-1,0,1.05,1");
  ASSERT_TRUE(under);
  EXPECT_EQ(under->status, 200) << under->body;
  EXPECT_LE(nlohmann::json::parse(under->body).at("count").get<std::size_t>(), in_box - 1);
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

TEST(ServeClasses, AServerWithoutQueriesSaysItNeedsThem) {
  testing::TwoClassMap f;
  testing::ServerProcess server(SLAMVDB_CLI_PATH, {"serve", f.map.string(), "--port", "0", "--ignore-model-id"},
                                (f.tmp.path / "serve.log").string());
  ASSERT_GT(server.port(), 0) << server.output();
  httplib::Client client("127.0.0.1", server.port());
  const auto res = client.Get("/api/classes?bbox=-1,-1,-1,1,1,1");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 400) << res->body;
  const nlohmann::json refusal = nlohmann::json::parse(res->body);
  EXPECT_NE(refusal.at("error").at("message").get<std::string>().find("--queries"), std::string::npos) << res->body;
  EXPECT_EQ(server.stop(SIGTERM), 0);
}

}  // namespace
}  // namespace slamvdb
