#include "slamvdb/core/csv.hpp"

#include <stdexcept>

namespace slamvdb {

namespace {

void append_csv_field(std::string& out, std::string_view field) {
  if (field.find_first_of(",\"\r\n") == std::string_view::npos) {
    out.append(field);
    return;
  }
  out += '"';
  for (const char c : field) {
    if (c == '"') out += '"';
    out += c;
  }
  out += '"';
}

}  // namespace

std::string csv_field(std::string_view field) {
  std::string out;
  append_csv_field(out, field);
  return out;
}

CsvWriter::CsvWriter(std::initializer_list<std::string_view> header) : columns_(header.size()) {
  if (columns_ == 0) throw std::logic_error("a CSV table needs at least one column");
  append(header);
}

void CsvWriter::row(std::initializer_list<std::string_view> fields) {
  if (fields.size() != columns_)
    throw std::logic_error("a CSV row has " + std::to_string(fields.size()) + " fields, the header " +
                           std::to_string(columns_));
  append(fields);
  ++rows_;
}

void CsvWriter::append(std::initializer_list<std::string_view> fields) {
  bool first = true;
  for (const std::string_view field : fields) {
    if (!first) text_ += ',';
    first = false;
    // A lone empty field would be an empty line, which readers skip as no record at all.
    if (columns_ == 1 && field.empty()) text_ += "\"\"";
    else append_csv_field(text_, field);
  }
  text_ += '\n';
}

}  // namespace slamvdb
