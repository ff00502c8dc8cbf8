#include "slamvdb/io/npy.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <optional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/core/half.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

using testing::TempDir;

// An .npy file assembled by hand, so that every header field can be made wrong on purpose.
fs::path write_raw_npy(const fs::path& path, const std::string& descr, bool fortran, const std::string& shape,
                       const void* data, std::size_t bytes, const char* magic = "\x93NUMPY") {
  std::string header =
      fmt::format("{{'descr': '{}', 'fortran_order': {}, 'shape': {}, }}", descr, fortran ? "True" : "False", shape);
  header.append((64 - (10 + header.size() + 1) % 64) % 64, ' ');
  header.push_back('\n');
  std::ofstream out(path, std::ios::binary);
  out.write(magic, 6);
  out.put(1);
  out.put(0);
  out.put(static_cast<char>(header.size() & 0xff));
  out.put(static_cast<char>(header.size() >> 8));
  out << header;
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
  return path;
}

// Value of element (c, y, x) of the C x H x W test arrays.
float chw_value(int c, int y, int x, int H, int W) { return static_cast<float>((c * H + y) * W + x); }

std::vector<float> chw_array(int C, int H, int W) {
  std::vector<float> v(static_cast<std::size_t>(C) * H * W);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<float>(i);
  return v;
}

void expect_chw_layout(const FeatureMap& map, int C, int H, int W) {
  ASSERT_EQ(map.dim(), C);
  ASSERT_EQ(map.height(), H);
  ASSERT_EQ(map.width(), W);
  std::vector<float> pixel(static_cast<std::size_t>(C));
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      map.decode_pixel(x, y, pixel.data());
      for (int c = 0; c < C; ++c) ASSERT_EQ(pixel[c], chw_value(c, y, x, H, W)) << c << " " << y << " " << x;
    }
}

std::string error_of(const fs::path& path) {
  try {
    read_feature_npy(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(Npy, Float32RoundTripKeepsPixelMajorLayout) {
  TempDir tmp;
  FeatureMap map(37, 5, 41);  // sizes that are not multiples of the transpose tile
  for (std::size_t i = 0; i < map.size(); ++i) map.values()[i] = static_cast<float>(i) * 0.5f - 3.0f;
  write_feature_npy(tmp.path / "m.npy", map);
  const FeatureMap back = read_feature_npy(tmp.path / "m.npy");
  EXPECT_EQ(back.dim(), 37);
  EXPECT_EQ(back.height(), 5);
  EXPECT_EQ(back.width(), 41);
  EXPECT_EQ(back, map);
  FeatureMap reused(2, 100, 100);  // larger storage: shrinks to the file's shape
  read_feature_npy(tmp.path / "m.npy", reused);
  EXPECT_EQ(reused.dim(), 37);
  EXPECT_EQ(reused.width(), 41);
  EXPECT_EQ(reused, map);
  // Header plus data, the data 64-byte aligned as the format asks.
  EXPECT_EQ(fs::file_size(tmp.path / "m.npy") % 64, (map.size() * 4) % 64);
}

TEST(Npy, ReadsChwAndBatchedChwAsPixelMajor) {
  TempDir tmp;
  const int C = 3, H = 4, W = 5;
  const auto v = chw_array(C, H, W);
  expect_chw_layout(
      read_feature_npy(write_raw_npy(tmp.path / "a.npy", "<f4", false, "(3, 4, 5)", v.data(), v.size() * 4)), C, H, W);
  expect_chw_layout(
      read_feature_npy(write_raw_npy(tmp.path / "b.npy", "<f4", false, "(1, 3, 4, 5)", v.data(), v.size() * 4)), C, H,
      W);
}

// A float16 file stays fp16 (fusion reads half the bytes), transposed bit for bit.
TEST(Npy, ReadsFloat16AsFp16) {
  TempDir tmp;
  const int C = 2, H = 3, W = 7;
  const auto v = chw_array(C, H, W);  // small integers are exact in fp16
  std::vector<uint16_t> half(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) half[i] = float_to_half(v[i]);
  half[5] = 0x7e00;  // NaN and -Inf are kept as they are: fusion counts them
  half[6] = 0xfc00;
  const fs::path path = write_raw_npy(tmp.path / "h.npy", "<f2", false, "(2, 3, 7)", half.data(), half.size() * 2);
  const FeatureMap map = read_feature_npy(path);
  EXPECT_EQ(map.precision(), EmbeddingPrecision::kFloat16);
  EXPECT_EQ(map.bytes(), half.size() * 2);
  EXPECT_THROW(map.values(), Error);  // an fp32 reader is told, not handed reinterpreted bytes
  for (int c = 0; c < C; ++c)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        ASSERT_EQ(map.half_pixel(x, y)[c], half[(static_cast<std::size_t>(c) * H + y) * W + x]) << c << y << x;

  // Reading into a reused fp32 map switches it to fp16; an fp32 file switches it back.
  FeatureMap reused(C, H, W);
  read_feature_npy(path, reused);
  EXPECT_EQ(reused, map);
  half[5] = float_to_half(5.0f), half[6] = float_to_half(6.0f);
  expect_chw_layout(
      read_feature_npy(write_raw_npy(tmp.path / "h2.npy", "<f2", false, "(2, 3, 7)", half.data(), half.size() * 2)), C,
      H, W);
  read_feature_npy(write_raw_npy(tmp.path / "f.npy", "<f4", false, "(2, 3, 7)", v.data(), v.size() * 4), reused);
  EXPECT_EQ(reused.precision(), EmbeddingPrecision::kFloat32);
  expect_chw_layout(reused, C, H, W);
}

TEST(Npy, BadFilesAreErrorsThatSayWhy) {
  TempDir tmp;
  const auto v = chw_array(2, 2, 2);
  const std::vector<double> d(v.begin(), v.end());
  EXPECT_NE(
      error_of(write_raw_npy(tmp.path / "f8.npy", "<f8", false, "(2, 2, 2)", d.data(), d.size() * 8)).find("'<f8'"),
      std::string::npos);
  EXPECT_NE(
      error_of(write_raw_npy(tmp.path / "be.npy", ">f4", false, "(2, 2, 2)", v.data(), v.size() * 4)).find("'>f4'"),
      std::string::npos);
  EXPECT_NE(
      error_of(write_raw_npy(tmp.path / "fo.npy", "<f4", true, "(2, 2, 2)", v.data(), v.size() * 4)).find("fortran"),
      std::string::npos);
  EXPECT_NE(error_of(write_raw_npy(tmp.path / "tr.npy", "<f4", false, "(2, 2, 2)", v.data(), v.size() * 4 - 3))
                .find("truncated"),
            std::string::npos);
  EXPECT_NE(
      error_of(write_raw_npy(tmp.path / "tl.npy", "<f4", false, "(2, 2, 1)", v.data(), v.size() * 4)).find("trailing"),
      std::string::npos);
  EXPECT_NE(error_of(write_raw_npy(tmp.path / "mg.npy", "<f4", false, "(2, 2, 2)", v.data(), v.size() * 4, "\x93NUMPX"))
                .find("magic"),
            std::string::npos);
  EXPECT_NE(
      error_of(write_raw_npy(tmp.path / "2d.npy", "<f4", false, "(4, 2)", v.data(), v.size() * 4)).find("C x H x W"),
      std::string::npos);
  EXPECT_NE(error_of(write_raw_npy(tmp.path / "4d.npy", "<f4", false, "(2, 1, 2, 2)", v.data(), v.size() * 4))
                .find("C x H x W"),
            std::string::npos);
  EXPECT_NE(error_of(write_raw_npy(tmp.path / "0d.npy", "<f4", false, "(0, 2, 2)", v.data(), 0)).find("empty"),
            std::string::npos);
  EXPECT_NE(error_of(tmp.path / "missing.npy").find("missing.npy"), std::string::npos);
}

// Debian's interpreter (python3-numpy is a set-up dependency), if it has numpy.
std::optional<std::string> python_with_numpy() {
  if (std::system((std::string(SLAMVDB_PYTHON) + " -c 'import numpy' > /dev/null 2>&1").c_str()) == 0) return std::string(SLAMVDB_PYTHON);
  return std::nullopt;
}

TEST(Npy, AgreesWithNumpyInBothDirections) {
  const auto python = python_with_numpy();
  if (!python) GTEST_SKIP() << "no python3 with numpy";
  TempDir tmp;
  const int C = 3, H = 4, W = 5;
  const std::string script = fmt::format(
      "import numpy as np, sys\n"
      "a = np.arange({0}*{1}*{2}, dtype=np.float32).reshape({0}, {1}, {2})\n"
      "np.save('{3}/np32.npy', a)\n"
      "np.save('{3}/np16.npy', a.astype(np.float16)[None])\n"
      "b = np.load('{3}/ours.npy')\n"
      "sys.exit(0 if b.dtype == np.float32 and b.shape == a.shape and (b == a).all() else 3)\n",
      C, H, W, tmp.path.string());
  FeatureMap ours(C, H, W);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < C; ++c) ours.pixel(x, y)[c] = chw_value(c, y, x, H, W);
  write_feature_npy(tmp.path / "ours.npy", ours);
  std::ofstream(tmp.path / "check.py") << script;
  ASSERT_EQ(std::system(fmt::format("{} {}", *python, (tmp.path / "check.py").string()).c_str()), 0)
      << "numpy rejected or misread our file";
  expect_chw_layout(read_feature_npy(tmp.path / "np32.npy"), C, H, W);
  expect_chw_layout(read_feature_npy(tmp.path / "np16.npy"), C, H, W);
}

}  // namespace
}  // namespace slamvdb
