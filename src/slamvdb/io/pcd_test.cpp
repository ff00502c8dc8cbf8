#include "slamvdb/io/pcd.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iterator>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

using slamvdb::testing::error_of;
using slamvdb::testing::TempDir;

PcdCloud sample_cloud() {
  PcdCloud c;
  for (int i = 0; i < 500; ++i) {
    c.points.emplace_back(0.1f * i, -0.05f * i, std::sin(0.1f * i));
    c.intensity.push_back(static_cast<float>(i % 17));
    c.time.push_back(i / 500.0f);
  }
  c.points[7] = Vec3f::Constant(std::nanf(""));
  return c;
}

void expect_same(const PcdCloud& a, const PcdCloud& b) {
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t i = 0; i < a.points.size(); ++i) {
    if (std::isnan(a.points[i].x())) {
      EXPECT_TRUE(std::isnan(b.points[i].x()));
      continue;
    }
    EXPECT_NEAR((a.points[i] - b.points[i]).norm(), 0.0f, 1e-5f) << i;
  }
  EXPECT_EQ(a.intensity, b.intensity);
  EXPECT_EQ(a.time.size(), b.time.size());
}

TEST(Pcd, RoundTripsInEveryEncoding) {
  TempDir dir;
  const PcdCloud cloud = sample_cloud();
  for (const auto enc : {PcdEncoding::kAscii, PcdEncoding::kBinary, PcdEncoding::kBinaryCompressed}) {
    const auto file = dir.path / "cloud.pcd";
    write_pcd(file, cloud, enc);
    expect_same(cloud, read_pcd(file));
  }
}

TEST(Pcd, ReadsHandWrittenAsciiWithMixedTypesCountsAndPadding) {
  TempDir dir;
  const auto file = dir.path / "hand.pcd";
  std::ofstream(file) << "# a comment\nVERSION .7\nFIELDS rgb x y z _ ring intensity\nSIZE 4 8 8 4 1 2 1\n"
                         "TYPE U F F F U U U\nCOUNT 1 1 1 1 3 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
                         "POINTS 2\nDATA ascii\n7 1.5 2.5 -3 0 0 0 12 200\n8 nan 0 0 0 0 0 13 100\n";
  const PcdCloud c = read_pcd(file);
  ASSERT_EQ(c.points.size(), 2u);
  EXPECT_EQ(c.points[0], Vec3f(1.5f, 2.5f, -3.0f));
  EXPECT_TRUE(std::isnan(c.points[1].x()));
  EXPECT_EQ(c.intensity, (std::vector<float>{200.0f, 100.0f}));
  EXPECT_TRUE(c.time.empty());
}

TEST(Pcd, ReadsBinaryWithPaddingFields) {
  TempDir dir;
  const auto file = dir.path / "padded.pcd";
  {
    std::ofstream out(file, std::ios::binary);
    out << "VERSION 0.7\nFIELDS x y z _ t\nSIZE 4 4 4 1 8\nTYPE F F F U F\nCOUNT 1 1 1 4 1\nWIDTH 3\nHEIGHT 1\n"
           "POINTS 3\nDATA binary\n";
    for (int i = 0; i < 3; ++i) {
      const float xyz[3] = {1.0f * i, 2.0f * i, 3.0f * i};
      const unsigned char pad[4] = {9, 9, 9, 9};
      const double t = 0.01 * i;
      out.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
      out.write(reinterpret_cast<const char*>(pad), sizeof pad);
      out.write(reinterpret_cast<const char*>(&t), sizeof t);
    }
  }
  const PcdCloud c = read_pcd(file);
  ASSERT_EQ(c.points.size(), 3u);
  EXPECT_EQ(c.points[2], Vec3f(2.0f, 4.0f, 6.0f));
  ASSERT_EQ(c.time.size(), 3u);
  EXPECT_FLOAT_EQ(c.time[2], 0.02f);
}

TEST(Pcd, MalformedFilesGiveErrorsNamingTheFile) {
  TempDir dir;
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir.path / name, std::ios::binary) << text;
    return dir.path / name;
  };
  const std::string header = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4\nHEIGHT 1\nPOINTS 4\n";
  const auto expect_error = [&](const std::filesystem::path& f, const std::string& part) {
    const std::string e = error_of([&] { read_pcd(f); });
    EXPECT_NE(e.find(f.filename().string()), std::string::npos) << e;
    EXPECT_NE(e.find(part), std::string::npos) << e;
  };
  expect_error(write("nodata.pcd", header), "no DATA");
  expect_error(write("noxyz.pcd", "FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nHEIGHT 1\nDATA ascii\n1 2 3\n"), "no x y z");
  expect_error(write("short.pcd", header + "DATA binary\n" + std::string(20, '\0')), "truncated");
  expect_error(write("shortascii.pcd", header + "DATA ascii\n1 2 3\n"), "truncated");
  expect_error(write("mismatch.pcd", "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n"), "SIZE");
  expect_error(write("type.pcd", "FIELDS x y z\nSIZE 4 4 3\nTYPE F F F\nWIDTH 1\nDATA ascii\n"), "unsupported");
  expect_error(write("lzf.pcd", header + "DATA binary_compressed\n" + std::string("\x08\0\0\0\x30\0\0\0", 8) +
                                    std::string(8, '\xff')), "LZF");
  expect_error(dir.path / "missing.pcd", "does not exist");
}

// The header's POINTS (= WIDTH x HEIGHT, PCD v0.7) must match the data: points beyond it would be
// lost unseen, so they are an error naming the file and where the extra data start, in every
// encoding; so is an ascii row with more or fewer values than FIELDS x COUNT, which would shift
// every later point.
TEST(Pcd, DataThatDoNotMatchTheHeaderAreErrorsSayingWhere) {
  TempDir dir;
  PcdCloud four;
  for (int i = 0; i < 4; ++i) four.points.emplace_back(1.0f * i, 2.0f, 3.0f);
  const auto declare_three = [&](const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    for (const std::string key : {"WIDTH 4\n", "POINTS 4\n"}) {
      const auto at = bytes.find(key);
      ASSERT_NE(at, std::string::npos) << key;
      bytes.replace(at, key.size(), key.substr(0, key.size() - 2) + "3\n");
    }
    std::ofstream(file, std::ios::binary | std::ios::trunc) << bytes;
  };
  const auto expect_error = [&](const std::filesystem::path& f, std::initializer_list<const char*> parts) {
    const std::string e = error_of([&] { read_pcd(f); });
    EXPECT_NE(e.find(f.string()), std::string::npos) << e;
    for (const char* part : parts) EXPECT_NE(e.find(part), std::string::npos) << "'" << part << "' in: " << e;
  };
  const auto ascii = dir.path / "ascii.pcd", binary = dir.path / "binary.pcd", packed = dir.path / "packed.pcd";
  write_pcd(ascii, four, PcdEncoding::kAscii);
  write_pcd(binary, four, PcdEncoding::kBinary);
  write_pcd(packed, four, PcdEncoding::kBinaryCompressed);
  for (const auto& f : {ascii, binary, packed}) ASSERT_EQ(read_pcd(f).points.size(), 4u);
  for (const auto& f : {ascii, binary, packed}) declare_three(f);
  // write_pcd's header has 11 lines, so the fourth point is on line 15.
  expect_error(ascii, {":15:", "go on after the 3 points", "WIDTH x HEIGHT = 3 x 1"});
  expect_error(binary, {"12 bytes follow the 3 points", "WIDTH x HEIGHT = 3 x 1"});
  expect_error(packed, {"compressed block would hold 48 bytes, expected 36 for 3 points"});

  // A compressed block with bytes after it.
  write_pcd(packed, four, PcdEncoding::kBinaryCompressed);
  std::ofstream(packed, std::ios::binary | std::ios::app) << "junk";
  expect_error(packed, {"4 bytes follow the 4 points"});

  const std::string header = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n";
  const auto rows = [&](const std::string& name, const std::string& data) {
    std::ofstream(dir.path / name, std::ios::binary) << header << data;
    return dir.path / name;
  };
  expect_error(rows("extra.pcd", "10 20 30\n40 50 60 70\n80 90 100\n"), {":9:", "point 1 has 4 values", "give 3 per point"});
  expect_error(rows("missing.pcd", "10 20 30\n40 50\n60 70 80\n"), {":9:", "point 1 has 2 values"});
  expect_error(rows("word.pcd", "10 20 30\n40 x 60\n70 80 90\n"), {":9:", "'x' of point 1 is not a number"});
  expect_error(rows("fewer.pcd", "10 20 30\n40 50 60\n"), {"truncated", "2 of the 3 points"});
  // Blank lines and CRLF ends are not rows.
  const PcdCloud blank = read_pcd(rows("blank.pcd", "1 2 3\r\n\n4 5 6\n  \n7 8 9\n\n"));
  ASSERT_EQ(blank.points.size(), 3u);
  EXPECT_EQ(blank.points[2], Vec3f(7, 8, 9));
}

// A FIFO named .pcd is refused (opened without waiting for a writer), not read until one comes.
TEST(Pcd, AFifoIsAnErrorNotAHang) {
  TempDir dir;
  const auto fifo = dir.path / "scan.pcd";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string e = error_of([&] { read_pcd(fifo); });
  EXPECT_NE(e.find("FIFO"), std::string::npos) << e;
  EXPECT_NE(e.find(fifo.string()), std::string::npos) << e;
}

// PCL itself (Debian's pcl-tools, optional: ~150 MB, so not in setup.sh) converts our binary file
// to ascii and binary_compressed; we must read its output back.
TEST(Pcd, ReadsWhatPclWrites) {
  const char* tool = "/usr/bin/pcl_convert_pcd_ascii_binary";
  if (!std::filesystem::exists(tool)) GTEST_SKIP() << "pcl-tools not installed";
  TempDir dir;
  PcdCloud cloud = sample_cloud();
  cloud.points[7] = Vec3f(1, 2, 3);
  write_pcd(dir.path / "ours.pcd", cloud, PcdEncoding::kBinary);
  for (const int format : {0, 1, 2}) {
    const auto out = dir.path / ("pcl" + std::to_string(format) + ".pcd");
    const std::string cmd = std::string(tool) + " " + (dir.path / "ours.pcd").string() + " " + out.string() + " " +
                            std::to_string(format) + " > /dev/null 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    expect_same(cloud, read_pcd(out));
  }
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {
// Found by fuzz_pcd: header sizes were trusted before the bytes behind them (a 4 GB allocation).
TEST(PcdFuzzRegression, SizesBeyondTheFileAreErrorsNotAllocations) {
  const auto dir = std::filesystem::temp_directory_path() / ("slamvdb_pcd_fuzz_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string header = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {}\nHEIGHT 1\n"
                             "POINTS {}\nDATA {}\n";
  const auto write = [&](const std::string& name, const std::string& bytes) {
    std::ofstream(dir / name, std::ios::binary) << bytes;
    return dir / name;
  };
  const std::string compressed_sizes("\xf0\xff\xff\xff\x24\x00\x00\x00", 8);  // 4 GB packed, 36 bytes unpacked
  EXPECT_THROW(read_pcd(write("a.pcd", fmt::format(fmt::runtime(header), 3, 3, "binary_compressed") + compressed_sizes)),
               Error);
  EXPECT_THROW(read_pcd(write("b.pcd", fmt::format(fmt::runtime(header), 2000000000, 2000000000, "binary"))), Error);
  EXPECT_THROW(read_pcd(write("c.pcd", fmt::format(fmt::runtime(header), 2000000000, 2000000000, "ascii") + "1 2 3\n")),
               Error);
  EXPECT_THROW(read_pcd(write("d.pcd", fmt::format(fmt::runtime(header), "99999999999", "99999999999", "binary"))),
               Error);
  std::filesystem::remove_all(dir);
}
}  // namespace
}  // namespace slamvdb
