// The one CSV writer: fields quoted per RFC 4180 read back as written by a strict reader
// (testing/csv_reader.hpp), one record per row, whatever the text in them.
#include "slamvdb/core/csv.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

#include "slamvdb/testing/csv_reader.hpp"

namespace slamvdb {
namespace {

TEST(Csv, FieldsAreQuotedOnlyWhenNeeded) {
  EXPECT_EQ(csv_field("smooth"), "smooth");
  EXPECT_EQ(csv_field("-1.250"), "-1.250");
  EXPECT_EQ(csv_field(""), "");
  EXPECT_EQ(csv_field("a,b"), "\"a,b\"");
  EXPECT_EQ(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_field("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(csv_field("cr\r"), "\"cr\r\"");
}

TEST(Csv, HostileTextReadsBackAsOneFieldOfOneRecord) {
  const std::vector<std::string> hostile = {"a,b",          "a,b\nc,d,e", "\"", "\"\"", "x|y", "end,",
                                            ",start",       "\r\n",       "",   " spaced ",
                                            "\x1b[31mred", "abc\xe2\x80\xae" "fdp"};
  CsvWriter csv({"x", "class", "count"});
  for (std::size_t i = 0; i < hostile.size(); ++i) csv.row({std::to_string(i), hostile[i], "7"});
  EXPECT_EQ(csv.rows(), hostile.size());
  std::string error;
  const auto records = testing::read_csv_strict(csv.text(), &error);
  ASSERT_TRUE(records) << error << "\n" << csv.text();
  ASSERT_EQ(records->size(), hostile.size() + 1);
  EXPECT_EQ((*records)[0], (std::vector<std::string>{"x", "class", "count"}));
  for (std::size_t i = 0; i < hostile.size(); ++i)
    EXPECT_EQ((*records)[i + 1], (std::vector<std::string>{std::to_string(i), hostile[i], "7"})) << i;
}

TEST(Csv, ARowOfTheWrongWidthIsAProgrammingError) {
  CsvWriter csv({"a", "b"});
  EXPECT_THROW(csv.row({"1"}), std::logic_error);
  EXPECT_THROW(csv.row({"1", "2", "3"}), std::logic_error);
  // One column: an empty field is written "" (an empty line would be no record at all).
  CsvWriter one({"name"});
  one.row({""});
  EXPECT_EQ(one.text(), "name\n\"\"\n");
  EXPECT_EQ(testing::read_csv_strict(one.text())->size(), 2u);
}

TEST(CsvReaderForTests, RefusesWhatRfc4180Refuses) {
  EXPECT_FALSE(testing::read_csv_strict("a,b\"c\n"));
  EXPECT_FALSE(testing::read_csv_strict("\"a\"b\n"));
  EXPECT_FALSE(testing::read_csv_strict("\"open\n"));
  EXPECT_FALSE(testing::read_csv_strict("a\rb\n"));
  EXPECT_EQ(testing::read_csv_strict("a,\"b\r\nc\"\r\nd,\n")->at(1), (std::vector<std::string>{"d", ""}));
}

}  // namespace
}  // namespace slamvdb
