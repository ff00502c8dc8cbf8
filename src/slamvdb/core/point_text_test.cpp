// One strict parser for points given as text (`query --at`, `--at-csv`): every example of the
// audit (issue 26, class 3) is either read as the point written or refused with the reason.
#include "slamvdb/core/point_text.hpp"

#include <gtest/gtest.h>

#include <locale>
#include <fstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

using testing::error_of;

std::string point_error(const std::string& text) { return error_of([&] { parse_point(text, "--at"); }); }

TEST(PointText, CommasOrBlanksSeparateTheThreeNumbers) {
  // Before: "10 20 30" was (10, 0, 0) and "-5.625 15.125 -1.875" (-5.625, 5.125, 1.875).
  EXPECT_EQ(parse_point("10 20 30", "--at"), Vec3d(10, 20, 30));
  EXPECT_EQ(parse_point("-5.625 15.125 -1.875", "--at"), Vec3d(-5.625, 15.125, -1.875));
  EXPECT_EQ(parse_point("-5.625,15.125,-1.875", "--at"), Vec3d(-5.625, 15.125, -1.875));
  EXPECT_EQ(parse_point(" 1.5, -2 ,\t0 ", "--at"), Vec3d(1.5, -2, 0));
  EXPECT_EQ(parse_point("1\t2\t3", "--at"), Vec3d(1, 2, 3));
  EXPECT_EQ(parse_point("1  \t 2 3", "--at"), Vec3d(1, 2, 3));
  EXPECT_EQ(parse_point("+1,.5,2.5e3", "--at"), Vec3d(1, 0.5, 2500));
  EXPECT_EQ(parse_point("\"1\",\"2\",\"-3\"", "--at"), Vec3d(1, 2, -3));  // quoted, as spreadsheets write
  EXPECT_EQ(parse_point("1e-3,-0,123456789.125", "--at"), Vec3d(0.001, 0, 123456789.125));
}

TEST(PointText, AnythingElseIsRefusedWithTheReason) {
  // Before: 0x10,0,0 was (0, 10, 0); 1,2,3,4 and 1,2,3abc lost their ends.
  EXPECT_NE(point_error("0x10,0,0").find("'0x10' is not a decimal number"), std::string::npos);
  EXPECT_NE(point_error("1,2,3,4").find("4 fields, expected 3"), std::string::npos);
  EXPECT_NE(point_error("1,2,3abc").find("'3abc' is not a decimal number"), std::string::npos);
  EXPECT_NE(point_error("1 2 3 4").find("4 fields"), std::string::npos);
  EXPECT_NE(point_error("1,2").find("2 fields"), std::string::npos);
  EXPECT_NE(point_error("1 2,3").find("2 fields"), std::string::npos);  // commas, so "1 2" is one field
  EXPECT_NE(point_error("1,,3").find("empty"), std::string::npos);
  EXPECT_NE(point_error("").find("empty"), std::string::npos);
  EXPECT_NE(point_error("nan,0,0").find("'nan' is not a finite number"), std::string::npos);
  EXPECT_NE(point_error("0,inf,0").find("not a finite number"), std::string::npos);
  EXPECT_NE(point_error("0,0,1e400").find("beyond the range"), std::string::npos);
  EXPECT_NE(point_error("1;2;3").find("1 field,"), std::string::npos);
  EXPECT_NE(point_error("1,5;2;3,4").find("'5;2;3'"), std::string::npos);
  EXPECT_NE(point_error("+-1,0,0").find("'+-1'"), std::string::npos);
  EXPECT_NE(point_error("1.5.2,0,0").find("'1.5.2'"), std::string::npos);
  EXPECT_NE(point_error("\"1,2,3\"").find("is not a decimal number"), std::string::npos);
  EXPECT_NE(point_error("1,2,\x1b[2J").find("\\x1b[2J"), std::string::npos);  // quoted with controls escaped
  EXPECT_EQ(point_error("1,2,3,4").rfind("--at: '1,2,3,4' is not x,y,z: ", 0), 0u) << point_error("1,2,3,4");
}

// A locale whose decimal mark is a comma (as de_DE), for the C++ streams.
struct DecimalComma : std::numpunct<char> {
  char do_decimal_point() const override { return ','; }
};

TEST(PointText, NumberListsReadLikePointsWithTheirOwnCount) {
  EXPECT_EQ(parse_numbers("1,2", "--near", 2, 3, "x,y[,z]"), (std::vector<double>{1, 2}));
  EXPECT_EQ(parse_numbers("-1 2.5 3e1", "--near", 2, 3, "x,y[,z]"), (std::vector<double>{-1, 2.5, 30}));
  EXPECT_EQ(parse_numbers("0,0,0,1,1,1", "--bbox", 6, 6, "a box").size(), 6u);
  const std::string few = error_of([] { parse_numbers("1", "--near", 2, 3, "x,y[,z]"); });
  EXPECT_NE(few.find("--near: '1' is not x,y[,z]: 1 field, expected 2 to 3"), std::string::npos) << few;
  const std::string bad = error_of([] { parse_numbers("0,0,0,1,1,nan", "--bbox", 6, 6, "a box"); });
  EXPECT_NE(bad.find("'nan' is not"), std::string::npos) << bad;
  EXPECT_NE(bad.find("--bbox"), std::string::npos) << bad;
}

TEST(PointText, TheLocaleDoesNotChangeTheDecimalMark) {
  const std::locale before = std::locale::global(std::locale(std::locale::classic(), new DecimalComma));
  const Vec3d p = parse_point("1.5 -2.25 3", "--at");
  const std::string comma = point_error("1,5 2 3");
  std::locale::global(before);
  EXPECT_EQ(p, Vec3d(1.5, -2.25, 3));
  EXPECT_NE(comma.find("2 fields"), std::string::npos) << comma;
}

TEST(PointText, FilesTakeTheSameRowsWithAnOptionalHeaderAndBom) {
  // Space- and tab-separated rows (before: misread), CRLF line ends, blank lines.
  PointsText t = parse_points_text("1 2 3\n4\t5\t6\r\n\n  \n-7.5, 8, 9\n", "p.txt");
  EXPECT_EQ(t.points, (std::vector<Vec3d>{{1, 2, 3}, {4, 5, 6}, {-7.5, 8, 9}}));
  EXPECT_FALSE(t.header);
  EXPECT_EQ(t.blank_lines, 2u);
  // A header when the first line holds no number; a UTF-8 byte order mark before it (before: the
  // BOM made the first point a "header" and the file gave 0 points).
  for (const std::string header : {"x,y,z\n", "X Y Z\n", "\"x\",\"y\",\"z\"\n", "\xEF\xBB\xBFx,y,z\n", "\xEF\xBB\xBF"})
    EXPECT_EQ(parse_points_text(header + "1,2,3\n", "p.csv").points, (std::vector<Vec3d>{{1, 2, 3}})) << header;
  EXPECT_TRUE(parse_points_text("x,y,z\n1,2,3", "p.csv").header);
  EXPECT_FALSE(parse_points_text("\xEF\xBB\xBF" "1,2,3", "p.csv").header);
  // Quoted numbers (before: taken as a header).
  EXPECT_EQ(parse_points_text("\"1\",\"2\",\"3\"\n", "p.csv").points, (std::vector<Vec3d>{{1, 2, 3}}));
}

TEST(PointText, ABadLineIsAnErrorNamingTheFileAndLine) {
  const auto file_error = [](const std::string& text) {
    return error_of([&] { parse_points_text(text, "pts.csv"); });
  };
  // A first line with a number is data, not a header (before: nan,0,0 was skipped as a header).
  EXPECT_NE(file_error("nan,0,0\n1,2,3\n").find("pts.csv:1: 'nan,0,0' is not x,y,z: 'nan' is not a finite"),
            std::string::npos);
  EXPECT_NE(file_error("1,2,3abc\n").find("pts.csv:1:"), std::string::npos);
  EXPECT_NE(file_error("1,2,3\n\n4,5\n").find("pts.csv:3: '4,5' is not x,y,z: 2 fields"), std::string::npos);
  EXPECT_NE(file_error("1,2,3\nx,y,z\n").find("pts.csv:2:"), std::string::npos);  // a header only first
  EXPECT_NE(file_error("x,y\n1,2,3\n").find("pts.csv:1:"), std::string::npos);    // a header has 3 fields
  EXPECT_NE(file_error("1,2,3,4\n").find("4 fields"), std::string::npos);
  EXPECT_NE(file_error("0x10,0,0\r\n").find("pts.csv:1: '0x10,0,0' is not"), std::string::npos);  // no CR shown
}

TEST(PointText, ReadsARegularFileNamingIt) {
  testing::TempDir tmp;
  const auto file = tmp.path / "points.csv";
  std::ofstream(file) << "x,y,z\n1,2,3\n4 5 6\n";
  EXPECT_EQ(read_points_file(file).points, (std::vector<Vec3d>{{1, 2, 3}, {4, 5, 6}}));
  std::ofstream(file) << "1,2,3\n1,2,3,4\n";
  EXPECT_NE(error_of([&] { read_points_file(file); }).find(file.string() + ":2:"), std::string::npos);
  EXPECT_NE(error_of([&] { read_points_file(tmp.path); }).find("directory"), std::string::npos);
}

}  // namespace
}  // namespace slamvdb
