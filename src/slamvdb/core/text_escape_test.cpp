#include "slamvdb/core/text_escape.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace slamvdb {
namespace {

TEST(TextEscape, PrintableTextIsUnchanged) {
  EXPECT_EQ(escape_control("lseg-vitb16 (tall grass) C:\\models"), "lseg-vitb16 (tall grass) C:\\models");
  EXPECT_EQ(escape_control("Gr\xc3\xa4ser \xe6\x9c\xa8 \xf0\x9f\x8c\xb2"), "Gr\xc3\xa4ser \xe6\x9c\xa8 \xf0\x9f\x8c\xb2");
  EXPECT_EQ(escape_control(""), "");
}

TEST(TextEscape, ControlCharactersBecomeVisible) {
  // An ANSI sequence that would clear the screen, a carriage return that would overwrite the line.
  EXPECT_EQ(escape_control("model\x1b[2J\rfake"), "model\\x1b[2J\\rfake");
  EXPECT_EQ(escape_control(std::string("a\0b\tc\nd\x7f", 8)), "a\\x00b\\tc\\nd\\x7f");
  EXPECT_EQ(escape_control("\xc2\x9b" "31m"), "\\u{009b}31m");            // C1 CSI in UTF-8
  EXPECT_EQ(escape_control("abc\xe2\x80\xae" "fdp.exe"), "abc\\u{202e}fdp.exe");  // right-to-left override
  EXPECT_EQ(escape_control("x\xe2\x80\xa8y"), "x\\u{2028}y");              // line separator
}

TEST(TextEscape, InvalidUtf8BytesAreEscapedOneByOne) {
  EXPECT_EQ(escape_control("\x9b[31m"), "\\x9b[31m");         // a raw 8-bit CSI
  EXPECT_EQ(escape_control("\xc0\xaf"), "\\xc0\\xaf");        // overlong '/'
  EXPECT_EQ(escape_control("\xed\xa0\x80"), "\\xed\\xa0\\x80");  // surrogate
  EXPECT_EQ(escape_control("ab\xe6\x9c"), "ab\\xe6\\x9c");    // truncated sequence at the end
  EXPECT_EQ(escape_control("\xf4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");  // above U+10FFFF
}

TEST(TextEscape, LongTextIsCut) {
  EXPECT_EQ(escape_control(std::string(100, 'a'), 10), "aaaaaaaaaa... (90 more bytes)");
  EXPECT_EQ(escape_control("abc", 3), "abc");
}

TEST(TextEscape, KeepLinesKeepsOnlyNewlines) {
  EXPECT_EQ(escape_control_keep_lines("one\ntwo\x1b[A\r\n"), "one\ntwo\\x1b[A\\r\n");
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

TEST(DisplayName, PrintableNamesUpTo64BytesPass) {
  for (const std::string& name : std::vector<std::string>{"smooth", "a,b", "say \"hi\"", "x|y", "dirt road",
                                                          "Gr\xc3\xa4ser \xe6\x9c\xa8", std::string(64, 'n')})
    EXPECT_EQ(display_name_problem(name), "") << name;
}

TEST(DisplayName, ControlCharactersBadUtf8LengthAndEdgeSpacesAreNamed) {
  EXPECT_NE(display_name_problem("red\x1b[31m").find("control character \\x1b at byte 4"), std::string::npos);
  EXPECT_NE(display_name_problem("abc\xe2\x80\xae" "fdp").find("\\u{202e}"), std::string::npos);  // RLO
  EXPECT_NE(display_name_problem("a\nb").find("\\n"), std::string::npos);
  EXPECT_NE(display_name_problem("a\tb").find("\\t"), std::string::npos);
  EXPECT_NE(display_name_problem("x\xc2\x85y").find("\\u{0085}"), std::string::npos);  // NEL, a C1 control
  EXPECT_NE(display_name_problem("ab\xff").find("not valid UTF-8 (byte 3 is \\xff)"), std::string::npos);
  EXPECT_NE(display_name_problem(std::string(65, 'n')).find("65 bytes"), std::string::npos);
  EXPECT_NE(display_name_problem("").find("empty"), std::string::npos);
  EXPECT_NE(display_name_problem(" grass").find("space"), std::string::npos);
  EXPECT_NE(display_name_problem("grass ").find("space"), std::string::npos);
}

TEST(MarkdownCell, PipesAndMarkupAreEscapedControlsMadeVisible) {
  EXPECT_EQ(markdown_cell("smooth"), "smooth");
  EXPECT_EQ(markdown_cell("a|b"), "a\\|b");
  EXPECT_EQ(markdown_cell("*x*_y_`z`"), "\\*x\\*\\_y\\_\\`z\\`");
  EXPECT_EQ(markdown_cell("a\\b"), "a\\\\b");
  EXPECT_EQ(markdown_cell("a\x1b[2J|\nb"), "a\\x1b\\[2J\\|\\nb");
  // A table row with the cell has as many unescaped '|' as one without.
  const auto separators = [](const std::string& row) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < row.size(); ++i) n += row[i] == '|' && (i == 0 || row[i - 1] != '\\');
    return n;
  };
  EXPECT_EQ(separators("| " + markdown_cell("x|y||z") + " | 1 |"), separators("| x | 1 |"));
}

}  // namespace
}  // namespace slamvdb
