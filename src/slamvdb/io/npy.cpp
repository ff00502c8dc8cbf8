#include "slamvdb/io/npy.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <fmt/std.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <functional>
#include <limits>
#include <numeric>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/half.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/core/output_file.hpp"

namespace slamvdb {

namespace {
static_assert(std::endian::native == std::endian::little, "npy I/O assumes a little-endian host");

constexpr char kMagic[] = "\x93NUMPY";
constexpr std::size_t kMagicSize = 6;

struct NpyHeader {
  std::string descr;
  bool fortran_order = false;
  std::vector<std::size_t> shape;
};

// Value of `key` in the header's Python dict literal, up to the next top-level ',' or '}'.
std::string dict_value(const std::string& dict, const std::string& key, const std::filesystem::path& path) {
  const auto k = dict.find("'" + key + "'");
  if (k == std::string::npos)
    throw Error(fmt::format("npy file {}: header has no '{}': {}", path, key, escape_control(dict, 200)));
  const auto colon = dict.find(':', k + key.size() + 2);
  const auto begin = colon == std::string::npos ? std::string::npos : dict.find_first_not_of(' ', colon + 1);
  if (begin == std::string::npos)
    throw Error(fmt::format("npy file {}: header has no value for '{}': {}", path, key, escape_control(dict, 200)));
  std::size_t end = begin;
  int depth = 0;
  for (; end < dict.size(); ++end) {
    const char c = dict[end];
    if (c == '(') ++depth;
    if (c == ')') --depth;
    if (depth == 0 && (c == ',' || c == '}')) break;
  }
  if (end == begin)
    throw Error(fmt::format("npy file {}: header has an empty value for '{}': {}", path, key,
                            escape_control(dict, 200)));
  return dict.substr(begin, end - begin);
}

NpyHeader parse_header(const std::string& dict, const std::filesystem::path& path) {
  NpyHeader h;
  std::string descr = dict_value(dict, "descr", path);
  if (descr.size() < 2 || (descr.front() != '\'' && descr.front() != '"'))
    throw Error(fmt::format("npy file {}: malformed dtype {}", path, escape_control(descr, 80)));
  h.descr = descr.substr(1, descr.size() - 2);
  const std::string fortran = dict_value(dict, "fortran_order", path);
  if (fortran != "False" && fortran != "True")
    throw Error(fmt::format("npy file {}: malformed fortran_order {}", path, escape_control(fortran, 80)));
  h.fortran_order = fortran == "True";
  const std::string shape = dict_value(dict, "shape", path);
  if (shape.size() < 2 || shape.front() != '(' || shape.back() != ')')
    throw Error(fmt::format("npy file {}: malformed shape {}", path, escape_control(shape, 80)));
  std::size_t pos = 1;
  while (pos < shape.size() - 1) {
    pos = shape.find_first_not_of(" ,", pos);
    if (pos >= shape.size() - 1) break;
    std::size_t dim = 0;
    const auto [next, ec] = std::from_chars(shape.data() + pos, shape.data() + shape.size(), dim);
    if (ec != std::errc() || dim > static_cast<std::size_t>(std::numeric_limits<int>::max()))
      throw Error(fmt::format("npy file {}: malformed shape {}", path, escape_control(shape, 80)));
    if (h.shape.size() == 32) throw Error(fmt::format("npy file {}: shape has more than 32 dimensions", path));
    h.shape.push_back(dim);
    pos = static_cast<std::size_t>(next - shape.data());
  }
  return h;
}

// Blocked transpose of a rows x cols matrix of T (row-major at `src`, any alignment) into a
// cols x rows float matrix; the tiles keep reads and writes within a few cache lines.
// rows x cols values of T at src (unaligned bytes) -> cols x rows values of Out at dst.
template <typename T, typename Out, typename Convert>
void transpose(const unsigned char* src, Out* dst, std::size_t rows, std::size_t cols, Convert convert) {
  constexpr std::size_t kTile = 32;
  const std::size_t col_tiles = (cols + kTile - 1) / kTile;
  tbb::parallel_for(std::size_t{0}, col_tiles, [&](std::size_t tile) {
    const std::size_t c0 = tile * kTile, c1 = std::min(cols, c0 + kTile);
    for (std::size_t r0 = 0; r0 < rows; r0 += kTile) {
      const std::size_t r1 = std::min(rows, r0 + kTile);
      for (std::size_t r = r0; r < r1; ++r)
        for (std::size_t c = c0; c < c1; ++c) {
          T value;
          std::memcpy(&value, src + (r * cols + c) * sizeof(T), sizeof(T));
          dst[c * rows + r] = convert(value);
        }
    }
  });
}

// The file mapped read-only: the transpose reads straight from the page cache, with no
// intermediate copy of what can be a 50 MB array.
class MappedFile {
 public:
  explicit MappedFile(const std::filesystem::path& path) {
    const RegularFile file(path, "npy file");  // a FIFO or device is refused, nothing blocks
    size_ = static_cast<std::size_t>(file.size());
    if (size_ > kMaxNpyFileBytes)
      throw Error(fmt::format("npy file {} is {} bytes, more than the limit of {} bytes", path, size_, kMaxNpyFileBytes));
    if (size_ > 0) {
      void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE | MAP_POPULATE, file.fd(), 0);
      if (p == MAP_FAILED) throw Error(fmt::format("cannot map npy file {}: {}", path, std::strerror(errno)));
      data_ = static_cast<const unsigned char*>(p);
    }
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<unsigned char*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const unsigned char* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  const unsigned char* data_ = nullptr;
  std::size_t size_ = 0;
};

// The header of a mapped .npy file and where its data starts; Error naming the file otherwise.
std::pair<NpyHeader, std::size_t> read_header(const MappedFile& file, const std::filesystem::path& path) {
  const unsigned char* bytes = file.data();
  if (file.size() < kMagicSize + 2 || std::memcmp(bytes, kMagic, kMagicSize) != 0)
    throw Error(fmt::format("{} is not an npy file (bad magic)", path));
  const int major = bytes[kMagicSize];
  if (major < 1 || major > 3) throw Error(fmt::format("npy file {}: unsupported format version {}", path, major));
  const std::size_t len_bytes = major == 1 ? 2 : 4, preamble = kMagicSize + 2 + len_bytes;
  if (file.size() < preamble) throw Error(fmt::format("npy file {} is truncated inside its header", path));
  std::size_t header_len = 0;
  for (std::size_t i = 0; i < len_bytes; ++i)
    header_len |= static_cast<std::size_t>(bytes[kMagicSize + 2 + i]) << (8 * i);
  if (file.size() < preamble + header_len) throw Error(fmt::format("npy file {} is truncated inside its header", path));
  return {parse_header(std::string(reinterpret_cast<const char*>(bytes + preamble), header_len), path),
          preamble + header_len};
}

}  // namespace

std::vector<std::vector<float>> read_npy_vectors(const std::filesystem::path& path) {
  const MappedFile file(path);
  const auto [h, offset] = read_header(file, path);
  if (h.descr != "<f4" && h.descr != "<f2")
    throw Error(fmt::format("npy file {}: dtype '{}' is not supported, expected float32 '<f4' or float16 '<f2'", path,
                            escape_control(h.descr, 40)));
  if (h.fortran_order && h.shape.size() == 2 && h.shape[0] > 1)
    throw Error(fmt::format("npy file {}: fortran_order arrays are not supported, save it C-ordered", path));
  if (h.shape.empty() || h.shape.size() > 2 || h.shape.back() == 0 || (h.shape.size() == 2 && h.shape[0] == 0))
    throw Error(fmt::format("npy file {}: shape ({}) is not (dim,) or (n, dim)", path, fmt::join(h.shape, ", ")));
  const std::size_t rows = h.shape.size() == 2 ? h.shape[0] : 1, dim = h.shape.back();
  const std::size_t element = h.descr == "<f4" ? 4 : 2;
  if (rows > (file.size() - offset) / element / dim + 1 || (file.size() - offset) != rows * dim * element)
    throw Error(fmt::format("npy file {}: shape ({}) needs {} bytes of data, found {}", path, fmt::join(h.shape, ", "),
                            rows * dim * element, file.size() - offset));
  std::vector<std::vector<float>> vectors(rows, std::vector<float>(dim));
  const unsigned char* data = file.data() + offset;
  for (std::size_t r = 0; r < rows; ++r)
    for (std::size_t c = 0; c < dim; ++c) {
      const std::size_t i = r * dim + c;
      if (element == 4) {
        std::memcpy(&vectors[r][c], data + 4 * i, 4);
      } else {
        uint16_t half;
        std::memcpy(&half, data + 2 * i, 2);
        vectors[r][c] = half_to_float(half);
      }
    }
  return vectors;
}

namespace {
}  // namespace

FeatureMap read_feature_npy(const std::filesystem::path& path) {
  FeatureMap map;
  read_feature_npy(path, map);
  return map;
}

void read_feature_npy(const std::filesystem::path& path, FeatureMap& map) {
  const MappedFile file(path);
  const auto [h, data_offset] = read_header(file, path);
  const std::size_t preamble = data_offset, header_len = 0;
  if (h.descr != "<f4" && h.descr != "<f2")
    throw Error(
        fmt::format("npy file {}: dtype '{}' is not supported, expected little-endian float32 '<f4' "
                    "or float16 '<f2'",
                    path, escape_control(h.descr, 40)));
  if (h.fortran_order)
    throw Error(fmt::format("npy file {}: fortran_order arrays are not supported, save it C-ordered", path));
  std::vector<std::size_t> shape = h.shape;
  if (shape.size() == 4 && shape[0] == 1) shape.erase(shape.begin());
  if (shape.size() != 3)
    throw Error(
        fmt::format("npy file {}: shape ({}) is not C x H x W or 1 x C x H x W", path, fmt::join(h.shape, ", ")));
  if (std::find(shape.begin(), shape.end(), 0) != shape.end())
    throw Error(fmt::format("npy file {}: empty feature map of shape ({})", path, fmt::join(h.shape, ", ")));

  // Dimensions are below 2^31 (checked when parsing): H * W fits, and the division keeps the
  // element count from overflowing before it is compared with the file size.
  const std::size_t channels = shape[0], pixels = shape[1] * shape[2];
  const std::size_t element = h.descr == "<f4" ? 4 : 2;
  if (channels > file.size() / pixels)
    throw Error(
        fmt::format("npy file {} is truncated: shape ({}) is larger than the file", path, fmt::join(h.shape, ", ")));
  const std::size_t expected = channels * pixels * element;
  const std::size_t found = file.size() - preamble - header_len;
  if (found != expected)
    throw Error(fmt::format("npy file {} {}: shape ({}) needs {} bytes of data, found {}", path,
                            found < expected ? "is truncated" : "has trailing bytes", fmt::join(h.shape, ", "),
                            expected, found));
  // '<f2' stays fp16 (no widening: fusion reads half the bytes); '<f4' is fp32.
  const auto identity = [](auto v) { return v; };
  if (element == 4) {
    map.reset(static_cast<int>(shape[0]), static_cast<int>(shape[1]), static_cast<int>(shape[2]));
    transpose<float>(file.data() + preamble + header_len, map.values().data(), channels, pixels, identity);
  } else {
    map.reset(static_cast<int>(shape[0]), static_cast<int>(shape[1]), static_cast<int>(shape[2]),
              EmbeddingPrecision::kFloat16);
    transpose<uint16_t>(file.data() + preamble + header_len, map.half_values().data(), channels, pixels, identity);
  }
}

void write_npy_array(const std::filesystem::path& path, const float* data, const std::vector<std::size_t>& shape) {
  write_npy_array(path, data, shape, NpyDtype::kFloat32);
}

void write_npy_array(const std::filesystem::path& path, const void* data, const std::vector<std::size_t>& shape,
                     NpyDtype dtype) {
  std::string dims = fmt::format("{}", fmt::join(shape, ", "));
  if (shape.size() == 1) dims += ',';  // Python's one-element tuple
  std::string header = fmt::format("{{'descr': '{}', 'fortran_order': False, 'shape': ({}), }}",
                                   dtype == NpyDtype::kFloat32 ? "<f4" : "<i4", dims);
  // The format pads the header with spaces and a newline so the data starts 64-byte aligned.
  const std::size_t unpadded = kMagicSize + 4 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header.push_back('\n');

  OutputFile out(path);  // a failed write (full disk, ...) leaves no partial .npy
  out.write(kMagic, kMagicSize);
  const unsigned char version_and_len[4] = {1, 0, static_cast<unsigned char>(header.size() & 0xff),
                                            static_cast<unsigned char>(header.size() >> 8)};
  out.write(version_and_len, 4);
  out.write(header);
  const std::size_t count = std::accumulate(shape.begin(), shape.end(), std::size_t{1}, std::multiplies<>());
  out.write(data, count * 4);  // both dtypes are 4 bytes
  out.commit();
}

void write_feature_npy(const std::filesystem::path& path, const FeatureMap& map) {
  const std::size_t pixels = map.pixels(), dim = static_cast<std::size_t>(map.dim());
  std::vector<float> chw(map.size());
  if (map.precision() == EmbeddingPrecision::kFloat32)
    transpose<float>(reinterpret_cast<const unsigned char*>(map.values().data()), chw.data(), pixels, dim,
                     [](float v) { return v; });
  else
    transpose<uint16_t>(reinterpret_cast<const unsigned char*>(map.half_values().data()), chw.data(), pixels, dim,
                        [](uint16_t h) { return half_to_float(h); });
  write_npy_array(path, chw.data(),
                  {dim, static_cast<std::size_t>(map.height()), static_cast<std::size_t>(map.width())});
}

}  // namespace slamvdb
