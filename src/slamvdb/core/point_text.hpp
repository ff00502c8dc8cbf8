#pragma once
// World points written as text: `query --at X,Y,Z`, a points file (`query --at-csv`), and any
// other reader of points (a server's request body). One strict parser, so that every way in reads
// the same text as the same point, or refuses it, never reads part of it.
//
// A point is three numbers x, y, z separated either by commas (with blanks around them if you
// like: "1.5, -2, 0") or by blanks alone ("1.5 -2 0"; spaces or tabs). A number is a decimal in
// the C locale as std::from_chars reads it, whole: an optional sign ('+' or '-'), digits with an
// optional '.' and exponent ("12", "-0.5", ".5", "2.5e3"); it may be enclosed in double quotes
// ("1.5", as spreadsheets export). Refused: hex ("0x10"), a decimal comma, anything after the
// number ("3abc"), a fourth field, nan and infinities, values beyond double's range.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

// The point in `text`; throws Error "<where>: '<text>' is not x,y,z: <reason>".
Vec3d parse_point(std::string_view text, std::string_view where);

// min_count..max_count numbers written as a point's are (commas or blanks, the same strict
// numbers): a box "xmin,ymin,zmin,xmax,ymax,zmax", a centre "x,y" or "x,y,z". Throws Error
// "<where>: '<text>' is not <shape>: <reason>".
std::vector<double> parse_numbers(std::string_view text, std::string_view where, std::size_t min_count,
                                  std::size_t max_count, std::string_view shape);

struct PointsText {
  std::vector<Vec3d> points;
  bool header = false;          // the first line was a header (x,y,z) and is not a point
  std::size_t blank_lines = 0;  // empty or blank lines, skipped
};

// A points file's text: one point per line (LF or CRLF line ends). A UTF-8 byte order mark at the
// start is skipped, and so are blank lines. The first non-blank line is a header, not a point,
// when it has three fields none of which begins like a number ("x,y,z", "X Y Z"); any other line
// that is not a point throws Error "<source>:<line>: '<line>' is not x,y,z: <reason>".
PointsText parse_points_text(std::string_view text, std::string_view source);

// Largest points file read: 256 MiB (about 10 million points).
inline constexpr std::uint64_t kMaxPointsFileBytes = std::uint64_t{256} << 20;

// parse_points_text of a regular file (read_regular_file: a FIFO or device is an Error naming it).
PointsText read_points_file(const std::filesystem::path& file);

}  // namespace slamvdb
