// `slamvdb query` similarity answers carry what the map knows of each voxel: its observations'
// weight and spread, and with --queries its class and confidence, the same as `query --at` gives.
#include <gtest/gtest.h>

#include <cstdlib>

#include "cli_files_fixture.hpp"
#include "slamvdb/testing/csv_reader.hpp"

namespace slamvdb::testing {
namespace {

class QueryAnswers : public CliFiles {};

CsvRecords csv_of(const std::filesystem::path& p) {
  std::string error;
  const auto records = read_csv_strict(CliFiles::slurp(p), &error);
  EXPECT_TRUE(records) << p << ": " << error;
  return records ? *records : CsvRecords{};
}

TEST_F(QueryAnswers, SimilarityResultsCarryStatisticsAndTheConfidenceOfQueryAt) {
  // Without a query set: weight and spread columns.
  const auto plain = run_cli("query " + q(map()) + " --class rough --queries " + q(queries()) + " --top-k 40 -o " +
                             q(file("plain.csv")));
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  EXPECT_NE(plain.output.find("| class | confidence |"), std::string::npos) << plain.output;
  const auto with = csv_of(file("plain.csv"));
  ASSERT_EQ(with.size(), 41u);
  const std::vector<std::string> header{"rank", "x", "y", "z", "score", "count", "weight", "spread", "class", "confidence"};
  EXPECT_EQ(with[0], header);
  const auto text = run_cli("query " + q(map()) + " --text grass --sim-seed 1 --top-k 40 -o " + q(file("text.csv")));
  ASSERT_EQ(text.exit_code, 0) << text.output;
  EXPECT_EQ(text.output.find("confidence"), std::string::npos) << text.output;
  const auto no_classes = csv_of(file("text.csv"));
  ASSERT_GT(no_classes.size(), 1u);
  EXPECT_EQ(no_classes[0], std::vector<std::string>(header.begin(), header.begin() + 8));

  // The paper's rule weighs each view 1: a cell seen by more views has a larger weight.
  std::string points = "x,y,z\n";
  for (std::size_t i = 1; i < with.size(); ++i) {
    EXPECT_DOUBLE_EQ(std::atof(with[i][6].c_str()), std::atof(with[i][5].c_str())) << "row " << i;
    EXPECT_FALSE(with[i][7].empty());  // a format-3 map knows the spread
    points += with[i][1] + "," + with[i][2] + "," + with[i][3] + "\n";
  }
  // The same cells looked up with --at: the same statistics, class and confidence.
  { std::ofstream(file("centres.csv")) << points; }
  const auto at = run_cli("query " + q(map()) + " --at-csv " + q(file("centres.csv")) + " --queries " + q(queries()) +
                          " -o " + q(file("at.csv")));
  ASSERT_EQ(at.exit_code, 0) << at.output;
  const auto looked_up = csv_of(file("at.csv"));
  ASSERT_EQ(looked_up.size(), with.size());
  std::size_t confident = 0;
  for (std::size_t i = 1; i < with.size(); ++i) {
    const auto& s = with[i];
    const auto& a = looked_up[i];  // x,y,z,found,cell_x,cell_y,cell_z,count,class,score,margin,weight,spread,confidence
    ASSERT_EQ(a[3], "1");
    EXPECT_EQ(a[7], s[5]);
    EXPECT_EQ(a[11], s[6]);
    EXPECT_NEAR(std::atof(a[12].c_str()), std::atof(s[7].c_str()), 1e-4 * (1 + std::atof(s[7].c_str())));
    if (std::atof(a[10].c_str()) > 1e-3) {
      EXPECT_EQ(a[8], s[8]) << "row " << i;
    }
    EXPECT_NEAR(std::atof(a[13].c_str()), std::atof(s[9].c_str()), 2e-4) << "row " << i;
    confident += std::atof(s[9].c_str()) > 0;
  }
  EXPECT_GT(confident, 0u);
}

}  // namespace
}  // namespace slamvdb::testing
