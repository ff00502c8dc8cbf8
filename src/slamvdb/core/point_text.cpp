#include "slamvdb/core/point_text.hpp"

#include <fmt/format.h>

#include <array>
#include <charconv>
#include <cmath>
#include <optional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/core/text_escape.hpp"

namespace slamvdb {
namespace point_text_detail {

bool is_blank(char c) { return c == ' ' || c == '\t'; }

std::string_view trim_blanks(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return s;
}

// The fields of one line: split at commas when it has one (blanks around fields trimmed), else at
// runs of blanks.
std::vector<std::string_view> split_fields(std::string_view line) {
  std::vector<std::string_view> fields;
  line = trim_blanks(line);
  if (line.find(',') != std::string_view::npos) {
    while (true) {
      const std::size_t comma = line.find(',');
      fields.push_back(trim_blanks(line.substr(0, comma)));
      if (comma == std::string_view::npos) break;
      line.remove_prefix(comma + 1);
    }
    return fields;
  }
  while (!line.empty()) {
    std::size_t end = 0;
    while (end < line.size() && !is_blank(line[end])) ++end;
    fields.push_back(line.substr(0, end));
    line = trim_blanks(line.substr(end));
  }
  return fields;
}

std::string_view unquote(std::string_view field) {
  if (field.size() >= 2 && field.front() == '"' && field.back() == '"') return field.substr(1, field.size() - 2);
  return field;
}

// The number in `field`, or why it is none.
std::optional<double> parse_number(std::string_view field, std::string& problem) {
  const std::string_view quoted = field;
  field = unquote(field);
  if (field.empty()) {
    problem = quoted.empty() ? "a field is empty" : "a quoted field is empty";
    return std::nullopt;
  }
  // from_chars takes '-' but no '+' (and no "+-1").
  if (field.front() == '+' && field.size() > 1 && field[1] != '-' && field[1] != '+') field.remove_prefix(1);
  double v = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
  const auto shown = [&] { return escape_control(quoted, 40); };
  if (ec == std::errc::result_out_of_range) {
    problem = fmt::format("'{}' is beyond the range of a double", shown());
  } else if (ec != std::errc() || end != field.data() + field.size()) {
    problem = fmt::format("'{}' is not a decimal number", shown());
  } else if (!std::isfinite(v)) {
    problem = fmt::format("'{}' is not a finite number", shown());
  } else {
    return v;
  }
  return std::nullopt;
}

// Whether a field starts like a number (then a line holding it is data, good or bad, not a header).
bool looks_numeric(std::string_view field) {
  field = unquote(field);
  if (!field.empty() && field.front() == '+') field.remove_prefix(1);
  double v = 0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), v);
  return ec == std::errc() || ec == std::errc::result_out_of_range;
}

std::optional<Vec3d> parse_fields(const std::vector<std::string_view>& fields, std::string& problem) {
  if (fields.size() != 3) {
    problem = fields.empty() ? "it is empty"
                             : fmt::format("{} field{}, expected 3 separated by commas or by blanks", fields.size(),
                                fields.size() == 1 ? "" : "s");
    return std::nullopt;
  }
  std::array<double, 3> xyz{};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto v = parse_number(fields[i], problem);
    if (!v) return std::nullopt;
    xyz[i] = *v;
  }
  return Vec3d(xyz[0], xyz[1], xyz[2]);
}

[[noreturn]] void fail(std::string_view where, std::string_view text, const std::string& problem) {
  throw Error(fmt::format("{}: '{}' is not x,y,z: {}", where, escape_control(text, 80), problem));
}

}  // namespace point_text_detail

Vec3d parse_point(std::string_view text, std::string_view where) {
  namespace d = point_text_detail;
  std::string problem;
  const auto point = d::parse_fields(d::split_fields(text), problem);
  if (!point) d::fail(where, text, problem);
  return *point;
}

std::vector<double> parse_numbers(std::string_view text, std::string_view where, std::size_t min_count,
                                  std::size_t max_count, std::string_view shape) {
  namespace d = point_text_detail;
  const std::vector<std::string_view> fields = d::split_fields(text);
  const auto refuse = [&](const std::string& problem) {
    throw Error(fmt::format("{}: '{}' is not {}: {}", where, escape_control(text, 80), shape, problem));
  };
  if (fields.size() < min_count || fields.size() > max_count)
    refuse(fields.empty() ? std::string("it is empty")
                          : fmt::format("{} field{}, expected {} separated by commas or by blanks", fields.size(),
                                        fields.size() == 1 ? "" : "s",
                                        min_count == max_count ? fmt::format("{}", min_count)
                                                               : fmt::format("{} to {}", min_count, max_count)));
  std::vector<double> out;
  std::string problem;
  for (const std::string_view field : fields) {
    const auto v = d::parse_number(field, problem);
    if (!v) refuse(problem);
    out.push_back(v.value_or(0.0));
  }
  return out;
}

PointsText parse_points_text(std::string_view text, std::string_view source) {
  namespace d = point_text_detail;
  PointsText out;
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // a UTF-8 byte order mark
  bool first = true;
  std::size_t line_no = 0;
  while (!text.empty()) {
    ++line_no;
    const std::size_t newline = text.find('\n');
    std::string_view line = text.substr(0, newline);
    text.remove_prefix(newline == std::string_view::npos ? text.size() : newline + 1);
    if (line.ends_with('\r')) line.remove_suffix(1);
    if (d::trim_blanks(line).empty()) {
      ++out.blank_lines;
      continue;
    }
    const std::vector<std::string_view> fields = d::split_fields(line);
    if (first) {
      first = false;
      if (fields.size() == 3 && !d::looks_numeric(fields[0]) && !d::looks_numeric(fields[1]) &&
          !d::looks_numeric(fields[2]) && !fields[0].empty() && !fields[1].empty() && !fields[2].empty()) {
        out.header = true;
        continue;
      }
    }
    std::string problem;
    const auto point = d::parse_fields(fields, problem);
    if (!point) d::fail(fmt::format("{}:{}", source, line_no), line, problem);
    out.points.push_back(*point);
  }
  return out;
}

PointsText read_points_file(const std::filesystem::path& file) {
  return parse_points_text(read_regular_file(file, "points file", kMaxPointsFileBytes), file.string());
}

}  // namespace slamvdb
