// Text in and out of the commands (issue 26, classes 3, 5 and 6): points given as text are read as
// written or refused; class names with CSV or markdown syntax stay in their fields and cells; names
// with control characters never reach a terminal; a huge but finite query vector is a query.
#include <gtest/gtest.h>

#include <fstream>

#include "slamvdb/io/npy.hpp"
#include "slamvdb/testing/csv_reader.hpp"
#include "slamvdb/testing/text_file.hpp"
#include "slamvdb/testing/two_class_map.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::CsvRecords;
using testing::read_csv_strict;
using testing::run_command;
using testing::shell_quote;

// The CSV a command wrote, read strictly (RFC 4180); every record as wide as the header.
CsvRecords strict_csv(const std::string& text, std::size_t columns) {
  std::string error;
  const auto records = read_csv_strict(text, &error);
  EXPECT_TRUE(records) << error << "\n" << text;
  if (!records) return {};
  for (const auto& r : *records) EXPECT_EQ(r.size(), columns) << text;
  return *records;
}

// Rows of a markdown table in `output` (lines starting with '|'): each with `cells` + 1 unescaped '|'.
void expect_markdown_cells(const std::string& output, std::size_t cells) {
  std::size_t start = 0, rows = 0;
  for (std::size_t end; (end = output.find('\n', start)) != std::string::npos; start = end + 1) {
    const std::string line = output.substr(start, end - start);
    if (line.empty() || line[0] != '|') continue;
    ++rows;
    std::size_t bars = 0;
    for (std::size_t i = 0; i < line.size(); ++i) bars += line[i] == '|' && (i == 0 || line[i - 1] != '\\');
    EXPECT_EQ(bars, cells + 1) << line;
  }
  EXPECT_GT(rows, 2u) << output;
}

TEST(QueryCommand, PointsAreReadAsWrittenOrRefused) {
  const testing::TwoClassMap f;
  const std::string query = "query " + shell_quote(f.map.string());
  // Before: "10 20 30" answered for (10, 0, 0) and "-5.625 15.125 -1.875" for (-5.625, 5.125, 1.875).
  for (const auto& [at, xyz] : std::vector<std::pair<std::string, std::vector<std::string>>>{
           {"10 20 30", {"10", "20", "30"}}, {"-5.625 15.125 -1.875", {"-5.625", "15.125", "-1.875"}}}) {
    const auto r =
        run_command(shell_quote(SLAMVDB_CLI_PATH) + " " + query + " --at " + shell_quote(at) + " 2>/dev/null");
    ASSERT_EQ(r.exit_code, 0) << at << "\n" << r.output;
    const CsvRecords rows = strict_csv(r.output, 15);
    ASSERT_EQ(rows.size(), 2u) << r.output;
    EXPECT_EQ(std::vector<std::string>(rows[1].begin(), rows[1].begin() + 3), xyz) << r.output;
  }
  // Before: 0x10,0,0 answered for (0, 10, 0); 1,2,3,4 and 1,2,3abc for (1, 2, 3). Usage errors now.
  for (const auto& [at, mention] : std::vector<std::pair<std::string, std::string>>{
           {"0x10,0,0", "'0x10' is not a decimal number"},
           {"1,2,3,4", "4 fields"},
           {"1,2,3abc", "'3abc'"},
           {"nan,0,0", "'nan' is not a finite number"}}) {
    const auto r = run_command(f.cli(query + " --at " + shell_quote(at)));
    EXPECT_EQ(r.exit_code, 2) << at << "\n" << r.output;
    EXPECT_NE(r.output.find("--at: '" + at + "' is not x,y,z: " + mention), std::string::npos) << r.output;
  }
  // --at-csv: the same parser. A BOM and a header are skipped; blank- and tab-separated rows and
  // quoted numbers are points (before: misread, or the file gave "0 points").
  const fs::path points = f.tmp.path / "points.csv";
  std::ofstream(points) << "\xEF\xBB\xBFx,y,z\r\n1 2 3\r\n4\t5\t6\n\"7\",\"8\",\"9\"\n\n";
  auto r = run_command(f.cli(query + " --at-csv " + shell_quote(points.string()) + " -o " + f.out("p.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("3 points"), std::string::npos) << r.output;
  const CsvRecords rows = strict_csv(testing::read_text_file(f.tmp.path / "p.csv"), 15);
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[3][0] + " " + rows[3][1] + " " + rows[3][2], "7 8 9");
  // A first line with a number is data (before: nan,0,0 or a BOM before numbers made it a header).
  for (const auto& [text, mention] : std::vector<std::pair<std::string, std::string>>{
           {"nan,0,0\n1,2,3\n", ":1: 'nan,0,0' is not x,y,z"},
           {"1,2,3\n1,2,3,4\n", ":2: '1,2,3,4' is not x,y,z: 4 fields"},
           {"x,y,z\n", "holds no point (only a header)"}}) {
    std::ofstream(points) << text;
    r = run_command(f.cli(query + " --at-csv " + shell_quote(points.string())));
    EXPECT_EQ(r.exit_code, 1) << text << "\n" << r.output;
    EXPECT_NE(r.output.find(points.string()), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(mention), std::string::npos) << r.output;
  }
  // The separators are stated in --help.
  r = run_command(f.cli("query --help"));
  EXPECT_NE(r.output.find("x,y,z or \"x y z\""), std::string::npos) << r.output;
}

TEST(TextOutputs, ClassNamesWithCsvAndMarkdownSyntaxStayInTheirFields) {
  const std::string comma_quote = "a,b \"q\"", pipe = "x|y";
  const testing::TwoClassMap f({comma_quote, pipe});
  const std::string map = shell_quote(f.map.string()), queries = " --queries " + shell_quote(f.queries.string());
  // classify -o ends with last_session (issue 23), export -o's CSV does not.
  const auto check_classified = [&](const fs::path& csv, std::size_t columns) {
    const CsvRecords rows = strict_csv(testing::read_text_file(csv), columns);
    ASSERT_EQ(rows.size(), f.semantic_cells + 1) << csv;
    for (std::size_t i = 1; i < rows.size(); ++i)
      EXPECT_EQ(rows[i][3], std::stod(rows[i][0]) < 0 ? comma_quote : pipe) << csv << " row " << i;
  };
  auto r = run_command(f.cli("classify " + map + queries + " -o " + f.out("c.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  check_classified(f.tmp.path / "c.csv", 9);
  expect_markdown_cells(r.output, 3);  // | class | voxels | share |
  EXPECT_NE(r.output.find("| x\\|y |"), std::string::npos) << r.output;

  r = run_command(f.cli("export " + map + queries + " -o " + f.out("e.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  check_classified(f.tmp.path / "e.csv", 8);

  const std::string at = " --at=-1,-1,0 --at 1,1,0 --at 100,0,0";
  r = run_command(f.cli("query " + map + queries + at + " -o " + f.out("p.csv")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const std::string& text :
       {testing::read_text_file(f.tmp.path / "p.csv"),
        run_command(shell_quote(SLAMVDB_CLI_PATH) + " query " + map + queries + at + " 2>/dev/null").output}) {
    const CsvRecords rows = strict_csv(text, 15);
    ASSERT_EQ(rows.size(), 4u) << text;
    EXPECT_EQ(rows[1][8], comma_quote) << text;
    EXPECT_EQ(rows[2][8], pipe) << text;
    EXPECT_EQ(rows[3][3] + rows[3][8], "0") << text;  // nothing there: no class
  }
}

TEST(TextOutputs, NamesWithControlCharactersAreRefusedAndNeverPrintedRaw) {
  const testing::TwoClassMap f;
  const std::string map = shell_quote(f.map.string());
  const std::string good = testing::read_text_file(f.queries);
  for (const std::string hostile : {"red\\u001b[31m", "abc\\u202efdp", "split\\nrow"}) {
    std::string text = good;
    text.replace(text.find("\"rough\""), 7, "\"" + hostile + "\"");
    std::ofstream(f.queries, std::ios::trunc) << text;
    const std::string queries = " --queries " + shell_quote(f.queries.string());
    for (const std::string& args :
         {"classify " + map + queries + " -o " + f.out("c.csv"), "export " + map + queries + " -o " + f.out("e.csv"),
          "query " + map + queries + " --at 1,1,0", "query " + map + queries + " --class smooth"}) {
      const auto r = run_command(f.cli(args));
      EXPECT_EQ(r.exit_code, 1) << args << "\n" << r.output;
      EXPECT_NE(r.output.find(f.queries.string() + ": the name of class 2"), std::string::npos) << r.output;
      EXPECT_EQ(r.output.find('\x1b'), std::string::npos) << r.output;
      EXPECT_EQ(r.output.find("\xe2\x80\xae"), std::string::npos) << r.output;
    }
    EXPECT_FALSE(fs::exists(f.tmp.path / "c.csv"));
    EXPECT_FALSE(fs::exists(f.tmp.path / "e.csv"));
  }
}

TEST(QueryCommand, AHugeFiniteVectorIsAQueryNotAZeroVector) {
  const testing::TwoClassMap f;
  const std::string map = shell_quote(f.map.string());
  // Before: "the composite query's terms cancel out: the result is a zero vector".
  const float huge[4] = {1e30f, 0, 0, 0}, zero[4] = {0, 0, 0, 0};
  write_npy_array(f.tmp.path / "huge.npy", huge, {4});
  write_npy_array(f.tmp.path / "zero.npy", zero, {4});
  auto r = run_command(f.cli("query " + map + " --vector " + f.out("huge.npy") + " --top-k 5"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("| 1 | -"), std::string::npos) << r.output;  // the best voxel has x < 0 (class 0)
  EXPECT_NE(r.output.find("| 1.0000 |"), std::string::npos) << r.output;  // cosine 1
  r = run_command(f.cli("query " + map + " --vector " + f.out("zero.npy")));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("positive term 1 is a zero vector"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace slamvdb
