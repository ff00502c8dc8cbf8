#pragma once
// CSV as RFC 4180 reads it, written by one writer: every CSV file slamvdb writes or prints goes
// through here, so that a field holding a comma, a double quote or a line break (a class name
// such as `a,b`) stays one field of one row for every reader (Python's csv, spreadsheets, pandas).
#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>

namespace slamvdb {

// `field` as one CSV field: unchanged unless it holds a comma, a double quote, CR or LF; then
// enclosed in double quotes, inner double quotes doubled (RFC 4180, section 2, rules 5-7).
std::string csv_field(std::string_view field);

// A CSV text: a header row, then rows of the same number of fields, each quoted as needed,
// joined by commas. Records end in '\n' (RFC 4180 writes CRLF; every CSV reader takes LF, and
// line-oriented tools read LF better). Numbers are formatted by the caller (they never need
// quoting): `csv.row({fmt::format("{:.3f}", x), name})`.
class CsvWriter {
 public:
  explicit CsvWriter(std::initializer_list<std::string_view> header);
  // Throws std::logic_error when the number of fields differs from the header's: a programming
  // error, not bad input.
  void row(std::initializer_list<std::string_view> fields);
  const std::string& text() const { return text_; }
  std::size_t rows() const { return rows_; }  // without the header
  std::size_t columns() const { return columns_; }

 private:
  void append(std::initializer_list<std::string_view> fields);
  std::string text_;
  std::size_t columns_ = 0, rows_ = 0;
};

}  // namespace slamvdb
