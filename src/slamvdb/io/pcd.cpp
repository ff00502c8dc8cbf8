#include "slamvdb/io/pcd.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <lzf.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/core/output_file.hpp"

namespace slamvdb {

namespace {
namespace fs = std::filesystem;

struct Field {
  std::string name;
  int size = 4;
  char type = 'F';
  int count = 1;
  std::size_t offset = 0;  // bytes into a point (binary) or into the field's block (compressed)
};

struct Header {
  std::vector<Field> fields;
  std::size_t width = 0, height = 1, points = 0, point_size = 0;
  std::string data;
  std::size_t data_offset = 0;  // bytes into the file where the data start
  std::size_t lines = 0;        // lines of the header (the data's first line is lines + 1)
};

std::vector<std::string> split(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

std::size_t parse_count(const std::string& text, const fs::path& file, const std::string& key) {
  std::size_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size())
    throw Error(fmt::format("{}: PCD header {} '{}' is not a non-negative integer", file, key, text));
  if (v >= (std::size_t{1} << 31))  // keeps every product of counts and sizes far from overflow
    throw Error(fmt::format("{}: PCD header {} {} is too large", file, key, v));
  return v;
}

// The next line of `text` from `at` (without its end of line); moves `at` past it.
bool next_pcd_line(std::string_view text, std::size_t& at, std::string& line) {
  if (at >= text.size()) return false;
  const std::size_t end = std::min(text.find('\n', at), text.size());
  line.assign(text.substr(at, end - at));
  if (!line.empty() && line.back() == '\r') line.pop_back();
  at = end + 1;
  return true;
}

Header read_header(std::string_view text, const fs::path& file) {
  Header h;
  std::vector<std::string> names, sizes, types, counts;
  bool have_points = false;
  std::string line;
  while (next_pcd_line(text, h.data_offset, line)) {
    ++h.lines;
    const auto words = split(line);
    if (words.empty() || words[0][0] == '#') continue;
    const std::string& key = words[0];
    const std::vector<std::string> values(words.begin() + 1, words.end());
    if (key == "VERSION" || key == "VIEWPOINT") continue;
    if (key == "FIELDS" || key == "COLUMNS") names = values;
    else if (key == "SIZE") sizes = values;
    else if (key == "TYPE") types = values;
    else if (key == "COUNT") counts = values;
    else if (key == "WIDTH" && values.size() == 1) h.width = parse_count(values[0], file, key);
    else if (key == "HEIGHT" && values.size() == 1) h.height = parse_count(values[0], file, key);
    else if (key == "POINTS" && values.size() == 1) h.points = parse_count(values[0], file, key), have_points = true;
    else if (key == "DATA" && values.size() == 1) {
      h.data = values[0];
      break;
    } else
      throw Error(fmt::format("{}: unexpected PCD header line '{}'", file, line));
  }
  h.data_offset = std::min(h.data_offset, text.size());
  if (h.data.empty()) throw Error(fmt::format("{}: not a PCD file (no DATA line in the header)", file));
  if (h.data != "ascii" && h.data != "binary" && h.data != "binary_compressed")
    throw Error(fmt::format("{}: unknown PCD DATA '{}' (ascii, binary or binary_compressed)", file, h.data));
  if (names.empty()) throw Error(fmt::format("{}: PCD header has no FIELDS", file));
  if (sizes.size() != names.size() || types.size() != names.size() || (!counts.empty() && counts.size() != names.size()))
    throw Error(fmt::format("{}: PCD header has {} FIELDS but {} SIZE, {} TYPE and {} COUNT entries", file,
                            names.size(), sizes.size(), types.size(), counts.size()));
  std::size_t offset = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    Field f;
    f.name = names[i];
    f.size = static_cast<int>(parse_count(sizes[i], file, "SIZE"));
    f.type = types[i].size() == 1 ? types[i][0] : '?';
    f.count = counts.empty() ? 1 : static_cast<int>(parse_count(counts[i], file, "COUNT"));
    const bool ok = (f.type == 'F' && (f.size == 4 || f.size == 8)) ||
                    ((f.type == 'I' || f.type == 'U') && (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8));
    if (!ok || f.count < 1)
      throw Error(fmt::format("{}: PCD field '{}' has unsupported TYPE {} SIZE {} COUNT {}", file, f.name, types[i],
                              f.size, f.count));
    f.offset = offset;
    offset += static_cast<std::size_t>(f.size) * f.count;
    h.fields.push_back(f);
  }
  h.point_size = offset;
  if (!have_points) h.points = h.width * h.height;
  if (h.points != h.width * h.height)
    throw Error(fmt::format("{}: PCD header says POINTS {} but WIDTH x HEIGHT = {} x {}", file, h.points, h.width,
                            h.height));
  return h;
}

double decode(const unsigned char* p, const Field& f) {
  const auto get = [&](auto v) {
    std::memcpy(&v, p, sizeof v);
    return static_cast<double>(v);
  };
  if (f.type == 'F') return f.size == 4 ? get(float{}) : get(double{});
  if (f.type == 'I') {
    switch (f.size) {
      case 1: return get(int8_t{});
      case 2: return get(int16_t{});
      case 4: return get(int32_t{});
      default: return get(int64_t{});
    }
  }
  switch (f.size) {
    case 1: return get(uint8_t{});
    case 2: return get(uint16_t{});
    case 4: return get(uint32_t{});
    default: return get(uint64_t{});
  }
}

const Field* find_field(const Header& h, std::initializer_list<const char*> names) {
  for (const char* n : names)
    for (const Field& f : h.fields)
      if (f.name == n) return &f;
  return nullptr;
}
}  // namespace

// The largest PCD payload read: 256 MiB (16.7 M points of x y z intensity t), as for scans; an
// ascii file may be up to 1 GiB of text.
constexpr std::uint64_t kMaxPcdDataBytes = std::uint64_t{256} << 20;

namespace {
// DATA ascii: one point per line (PCD v0.7), exactly as many values as FIELDS x COUNT give, and
// exactly POINTS lines; blank lines are ignored. A row with more or fewer values would shift every
// later point, and rows beyond POINTS would be lost: both are errors naming the line.
std::vector<double> parse_ascii_points(std::string_view text, const Header& h, std::size_t values_per_point,
                                       const fs::path& file) {
  const std::size_t remaining = text.size() - h.data_offset;
  // At least two characters (a digit and a separator) per value.
  if (values_per_point != 0 && h.points > remaining / 2 / values_per_point)
    throw Error(fmt::format("{}: truncated PCD data: {} points of {} values cannot fit in the {} bytes left", file,
                            h.points, values_per_point, remaining));
  std::vector<double> values;
  values.reserve(h.points * values_per_point);
  std::size_t at = h.data_offset, line_number = h.lines, points = 0;
  std::string line;
  while (next_pcd_line(text, at, line)) {
    ++line_number;
    const auto words = split(line);
    if (words.empty()) continue;
    if (points == h.points)
      throw Error(fmt::format("{}:{}: PCD data go on after the {} points the header declares (POINTS = WIDTH x "
                              "HEIGHT = {} x {}); the header does not match the data",
                              file, line_number, h.points, h.width, h.height));
    if (words.size() != values_per_point)
      throw Error(fmt::format("{}:{}: PCD point {} has {} values, but the header's FIELDS and COUNT give {} per point",
                              file, line_number, points, words.size(), values_per_point));
    for (const std::string& word : words) {
      double v = 0.0;
      if (word == "nan" || word == "NaN" || word == "-nan") v = std::numeric_limits<double>::quiet_NaN();
      else {
        const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), v);
        if (ec != std::errc() || end != word.data() + word.size())
          throw Error(fmt::format("{}:{}: PCD value '{}' of point {} is not a number", file, line_number, word, points));
      }
      values.push_back(v);
    }
    ++points;
  }
  if (points < h.points)
    throw Error(fmt::format("{}: truncated PCD data: {} of the {} points the header declares", file, points,
                            h.points));
  return values;
}

// Bytes after the data the header declares: the header's POINTS (= WIDTH x HEIGHT) is smaller
// than the data, whose rest would be lost unseen.
void refuse_trailing_bytes(std::size_t end, std::size_t size, const Header& h, const fs::path& file) {
  if (end < size)
    throw Error(fmt::format("{}: {} bytes follow the {} points the header declares (POINTS = WIDTH x HEIGHT = {} x {}; "
                            "data end at byte {}); the header does not match the data",
                            file, size - end, h.points, h.width, h.height, end));
}
}  // namespace

PcdCloud read_pcd(const fs::path& file) {
  // Read whole through RegularFile: a FIFO or device named .pcd is an error, not a read that blocks.
  const std::string text = read_regular_file(file, "PCD file");
  const Header h = read_header(text, file);
  const Field* fx = find_field(h, {"x"});
  const Field* fy = find_field(h, {"y"});
  const Field* fz = find_field(h, {"z"});
  if (!fx || !fy || !fz) throw Error(fmt::format("{}: PCD file has no x y z fields", file));
  const Field* fi = find_field(h, {"intensity", "reflectivity"});
  const Field* ft = find_field(h, {"t", "time", "timestamp"});
  // value(point, field) for the first element of a field, whatever the encoding.
  std::vector<unsigned char> bytes;
  std::vector<double> ascii_values;
  std::size_t values_per_point = 0;
  for (const Field& f : h.fields) values_per_point += f.count;
  std::vector<std::size_t> ascii_index(h.fields.size());
  for (std::size_t i = 0, k = 0; i < h.fields.size(); k += h.fields[i].count, ++i) ascii_index[i] = k;

  // Sizes from the header are checked against the bytes that follow before anything is allocated
  // (a header claiming 2^32 points made a 4 GB allocation; found by fuzz_pcd).
  const std::size_t at = h.data_offset;
  const std::size_t remaining = text.size() - at;
  if (h.point_size != 0 && h.points > remaining / h.point_size && h.data == "binary")
    throw Error(fmt::format("{}: truncated PCD data: {} points of {} bytes need more than the {} bytes left", file,
                            h.points, h.point_size, remaining));
  if (h.data != "ascii" && h.point_size != 0 && h.points > kMaxPcdDataBytes / h.point_size)
    throw Error(fmt::format("{}: PCD data of {} points x {} bytes is above the {} MiB limit", file, h.points,
                            h.point_size, kMaxPcdDataBytes >> 20));
  if (h.data == "ascii") {
    ascii_values = parse_ascii_points(text, h, values_per_point, file);
  } else if (h.data == "binary") {
    const std::size_t size = h.points * h.point_size;
    bytes.assign(text.begin() + static_cast<std::ptrdiff_t>(at), text.begin() + static_cast<std::ptrdiff_t>(at + size));
    refuse_trailing_bytes(at + size, text.size(), h, file);
  } else {
    uint32_t sizes[2] = {0, 0};
    if (remaining < sizeof sizes) throw Error(fmt::format("{}: truncated PCD data: no compressed sizes", file));
    std::memcpy(sizes, text.data() + at, sizeof sizes);
    if (sizes[1] != h.points * h.point_size)
      throw Error(fmt::format("{}: PCD compressed block would hold {} bytes, expected {} for {} points", file,
                              sizes[1], h.points * h.point_size, h.points));
    if (sizes[0] > remaining - sizeof sizes)
      throw Error(fmt::format("{}: truncated PCD data: compressed block of {} bytes, {} left", file, sizes[0],
                              remaining - sizeof sizes));
    const char* packed = text.data() + at + sizeof sizes;
    refuse_trailing_bytes(at + sizeof sizes + sizes[0], text.size(), h, file);
    bytes.resize(sizes[1]);
    if (sizes[1] > 0 && lzf_decompress(packed, sizes[0], bytes.data(), sizes[1]) != sizes[1])
      throw Error(fmt::format("{}: corrupt PCD compressed data (LZF)", file));
  }

  const bool compressed = h.data == "binary_compressed";
  const auto value = [&](std::size_t point, const Field& f) -> double {
    if (!ascii_values.empty() || h.data == "ascii")
      return ascii_values[point * values_per_point + ascii_index[&f - h.fields.data()]];
    // Compressed data are stored field by field (all points' values of a field together).
    const std::size_t at = compressed ? f.offset * h.points + point * f.size * f.count : point * h.point_size + f.offset;
    return decode(bytes.data() + at, f);
  };
  PcdCloud cloud;
  cloud.points.resize(h.points);
  for (std::size_t i = 0; i < h.points; ++i)
    cloud.points[i] = Vec3f(static_cast<float>(value(i, *fx)), static_cast<float>(value(i, *fy)),
                            static_cast<float>(value(i, *fz)));
  if (fi) {
    cloud.intensity.resize(h.points);
    for (std::size_t i = 0; i < h.points; ++i) cloud.intensity[i] = static_cast<float>(value(i, *fi));
  }
  if (ft) {
    cloud.time.resize(h.points);
    for (std::size_t i = 0; i < h.points; ++i) cloud.time[i] = static_cast<float>(value(i, *ft));
  }
  return cloud;
}

void write_pcd(const fs::path& file, const PcdCloud& cloud, PcdEncoding encoding) {
  const std::size_t n = cloud.points.size();
  if ((!cloud.intensity.empty() && cloud.intensity.size() != n) || (!cloud.time.empty() && cloud.time.size() != n))
    throw Error(fmt::format("cannot write {}: intensity/time sizes do not match {} points", file, n));
  std::vector<std::vector<float>> columns(3, std::vector<float>(n));
  std::string fields = "x y z";
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) columns[a][i] = cloud.points[i][a];
  if (!cloud.intensity.empty()) columns.push_back(cloud.intensity), fields += " intensity";
  if (!cloud.time.empty()) columns.push_back(cloud.time), fields += " t";
  const std::size_t nf = columns.size();
  const char* data = encoding == PcdEncoding::kAscii ? "ascii" : encoding == PcdEncoding::kBinary ? "binary" : "binary_compressed";
  const auto repeat = [nf](const char* word) {
    std::string s;
    for (std::size_t k = 0; k < nf; ++k) s += word;
    return s;
  };
  const std::string header = fmt::format(
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {}\nSIZE{}\nTYPE{}\nCOUNT{}\nWIDTH {}\n"
      "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\nDATA {}\n",
      fields, repeat(" 4"), repeat(" F"), repeat(" 1"), n, n, data);
  std::ostringstream out(std::ios::binary);  // written whole by the one output writer
  out << header;
  if (encoding == PcdEncoding::kAscii) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < nf; ++k) out << (k ? " " : "") << fmt::format("{}", columns[k][i]);
      out << '\n';
    }
  } else if (encoding == PcdEncoding::kBinary) {
    std::vector<float> row(nf);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < nf; ++k) row[k] = columns[k][i];
      out.write(reinterpret_cast<const char*>(row.data()), static_cast<std::streamsize>(nf * sizeof(float)));
    }
  } else {
    std::vector<float> soa;
    soa.reserve(n * nf);
    for (const auto& c : columns) soa.insert(soa.end(), c.begin(), c.end());
    const unsigned int raw = static_cast<unsigned int>(soa.size() * sizeof(float));
    std::vector<unsigned char> packed(raw + raw / 16 + 64);
    unsigned int size = raw == 0 ? 0 : lzf_compress(soa.data(), raw, packed.data(), static_cast<unsigned int>(packed.size()));
    if (raw > 0 && size == 0) throw Error(fmt::format("cannot write {}: LZF compression failed", file));
    const uint32_t sizes[2] = {size, raw};
    out.write(reinterpret_cast<const char*>(sizes), sizeof sizes);
    out.write(reinterpret_cast<const char*>(packed.data()), size);
  }
  write_output_file(file, std::move(out).str());
}

}  // namespace slamvdb
