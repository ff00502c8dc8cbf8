// Region questions over HTTP and on the command line: POST /api/query with a "region" and
// `slamvdb query --bbox / --near --radius` answer the same rows, and those are the rows of the
// unrestricted question whose cell lies in the region; a region outside the map answers no rows;
// a bad region is HTTP 400 naming the field and exit 2 naming the option.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "slamvdb/query/query_region.hpp"
#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

using testing::run_command;
using testing::shell_quote;

// The rows of `answer` without their rank (a region renumbers them).
std::vector<std::vector<std::string>> unranked_rows(std::vector<std::vector<std::string>> rows) {
  for (auto& row : rows) row.erase(row.begin());
  return rows;
}

// `whole` (an answer of every cell) limited to `region` and to its first `top_k` rows.
nlohmann::json restricted(const nlohmann::json& whole, const QueryRegion& region, std::size_t top_k) {
  nlohmann::json out = whole;
  out["results"] = nlohmann::json::array();
  for (const auto& r : whole.at("results")) {
    const auto& p = r.at("position");
    if (out["results"].size() < top_k && region.contains({p[0].get<double>(), p[1].get<double>(), p[2].get<double>()}))
      out["results"].push_back(r);
  }
  return out;
}

TEST(ServeRegion, AnswersAreTheWholeMapsAnswersInTheRegionAndEqualTheCli) {
  testing::ServedMap s;
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const std::vector<double> box{-1.1, -0.9, -1, 1.3, 1.05, 1}, cylinder{2, 1}, ball{-2, 1, 0}, far{100, 100, 0, 110, 110, 1};
  struct Case {
    nlohmann::json body;  // without region
    nlohmann::json region;
    QueryRegion expected_region;
    std::string cli_args;  // the same question on the command line
  };
  const std::vector<Case> cases = {
      {{{"text", "grass"}, {"top_k", 7}}, {{"bbox", box}}, make_region(std::span<const double>(box), {}, {}),
       "--text grass --top-k 7 --bbox=-1.1,-0.9,-1,1.3,1.05,1"},
      {{{"class", "rough"}, {"top_k", 12}}, {{"near", cylinder}, {"radius", 1.5}},
       make_region({}, std::span<const double>(cylinder), 1.5), "--class rough --top-k 12 --near 2,1 --radius 1.5"},
      {{{"class", "smooth"}, {"not_class", "rough"}, {"top_k", 400}},
       {{"bbox", box}, {"near", ball}, {"radius", 1.2}},
       make_region(std::span<const double>(box), std::span<const double>(ball), 1.2),
       "--class smooth --not-class rough --top-k 400 --bbox=-1.1,-0.9,-1,1.3,1.05,1 --near=-2,1,0 --radius 1.2"},
  };
  for (const Case& c : cases) {
    nlohmann::json whole_body = c.body, body = c.body;
    whole_body["top_k"] = 0;
    whole_body["threshold"] = -1;
    const nlohmann::json whole = s.post_query(whole_body);
    ASSERT_LT(whole.at("count").get<std::size_t>(), 10000u);  // every cell, not capped
    body["region"] = c.region;
    const nlohmann::json answer = s.post_query(body);
    EXPECT_EQ(answer.at("region"), c.region);
    const auto rows = testing::query_answer_rows(answer);
    ASSERT_FALSE(rows.empty()) << body.dump();
    EXPECT_LT(rows.size(), whole.at("count").get<std::size_t>());
    EXPECT_EQ(unranked_rows(rows),
              unranked_rows(testing::query_answer_rows(restricted(whole, c.expected_region, body["top_k"].get<std::size_t>()))))
        << body.dump();
    EXPECT_EQ(rows, s.cli_rows(c.cli_args)) << c.cli_args;
  }
  // A region outside the map: no rows, not an error, on both.
  const nlohmann::json nowhere = s.post_query({{"text", "grass"}, {"region", {{"bbox", far}}}});
  EXPECT_EQ(nowhere.at("count").get<std::size_t>(), 0u);
  EXPECT_TRUE(nowhere.at("results").empty());
  EXPECT_TRUE(s.cli_rows("--text grass --bbox 100,100,0,110,110,1").empty());

  // A bad region: 400 naming the field, exit 2 naming the option, both before any work.
  for (const auto& [region, field] : std::vector<std::pair<nlohmann::json, std::string>>{
           {{{"bbox", {0, 0, 0, 1, 1}}}, "region.bbox"},
           {{{"bbox", {0, 0, 3, 1, 1, 1}}}, "region.bbox"},
           {{{"near", {0, 0}}}, "region.radius"},
           {{{"near", {0, 0}}, {"radius", -1}}, "region.radius"},
           {{{"radius", 2}}, "region.near"},
           {{{"centre", {0, 0}}}, "region.centre"}}) {
    const nlohmann::json refusal = s.post_query({{"text", "grass"}, {"region", region}}, 400);
    EXPECT_EQ(refusal.at("error").at("field"), field) << region.dump();
  }
  for (const auto& [args, option] : std::vector<std::pair<std::string, std::string>>{
           {"--text grass --bbox 0,0,0,1,1", "--bbox"},
           {"--text grass --bbox 0,0,3,1,1,1", "--bbox: the z minimum 3 is above the maximum 1"},
           {"--text grass --near 0,0", "--radius"},
           {"--text grass --radius 2", "--near"},
           {"--text grass --near 0,0,0,0 --radius 1", "--near"},
           {"--text grass --radius 0 --near 1,1", "--radius"},
           {"--at 1,2,3 --bbox 0,0,0,1,1,1", "--bbox"}}) {
    const auto r = run_command(s.f.cli("query " + shell_quote(s.f.map.string()) + " --ignore-model-id " + args));
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(option), std::string::npos) << args << "\n" << r.output;
  }
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

}  // namespace
}  // namespace slamvdb
