#pragma once
// For tests only: a strict RFC 4180 reader, written apart from the library's CSV writer so that
// the writer is checked against the standard, not against itself. A record ends in LF or CRLF; a
// field is either plain (no comma, quote, CR or LF) or enclosed in double quotes with inner
// quotes doubled. Anything else (a quote inside a plain field, text after a closing quote, an
// unterminated quoted field, a lone CR) is an error.
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace slamvdb::testing {

using CsvRecords = std::vector<std::vector<std::string>>;

// The records of `text`, or nullopt with `error` set.
inline std::optional<CsvRecords> read_csv_strict(std::string_view text, std::string* error = nullptr) {
  const auto fail = [&](std::size_t at, const char* what) -> std::optional<CsvRecords> {
    if (error) *error = std::string(what) + " at byte " + std::to_string(at);
    return std::nullopt;
  };
  CsvRecords records;
  std::vector<std::string> record;
  std::size_t i = 0;
  while (i < text.size()) {
    std::string field;
    if (text[i] == '"') {
      ++i;
      while (true) {
        if (i >= text.size()) return fail(i, "unterminated quoted field");
        if (text[i] == '"') {
          if (i + 1 < text.size() && text[i + 1] == '"') {
            field += '"';
            i += 2;
            continue;
          }
          ++i;
          break;
        }
        field += text[i++];
      }
    } else {
      while (i < text.size() && text[i] != ',' && text[i] != '\n' && text[i] != '\r') {
        if (text[i] == '"') return fail(i, "a double quote inside an unquoted field");
        field += text[i++];
      }
    }
    record.push_back(std::move(field));
    if (i == text.size()) break;
    if (text[i] == ',') {
      ++i;
      if (i == text.size()) record.emplace_back();  // "a," ends with an empty field
      continue;
    }
    if (text[i] == '\r') {
      if (i + 1 >= text.size() || text[i + 1] != '\n') return fail(i, "a CR not followed by LF");
      ++i;
    }
    if (text[i] != '\n') return fail(i, "text after a closing quote");
    ++i;
    records.push_back(std::move(record));
    record.clear();
  }
  if (!record.empty()) records.push_back(std::move(record));
  return records;
}

}  // namespace slamvdb::testing
