#include "slamvdb/io/scan_io.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

using testing::TempDir;

template <typename T>
fs::path write_binary(const fs::path& path, const std::vector<T>& values, std::size_t extra_bytes = 0) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(values.data()), static_cast<std::streamsize>(values.size() * sizeof(T)));
  for (std::size_t i = 0; i < extra_bytes; ++i) out.put('\0');
  return path;
}

std::string error_of(const ScanRecord& record) {
  try {
    read_scan(record);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ScanIo, ReadsPointsIntensityAndLowSixteenLabelBits) {
  TempDir tmp;
  const auto bin = write_binary<float>(tmp.path / "0.bin", {1, 2, 3, 0.5f, -4, 5, -6, 0.25f});
  const auto label = write_binary<uint32_t>(tmp.path / "0.label", {0x00070003u, 17u});
  const LidarScan scan = read_scan({12.5, bin, label});
  EXPECT_DOUBLE_EQ(scan.stamp, 12.5);
  ASSERT_EQ(scan.points.size(), 2u);
  EXPECT_EQ(scan.points[1], Vec3f(-4, 5, -6));
  EXPECT_EQ(scan.intensity, (std::vector<float>{0.5f, 0.25f}));
  EXPECT_EQ(scan.labels, (std::vector<uint16_t>{3, 17}));  // instance id in the high bits is dropped
}

TEST(ScanIo, EmptyFileIsAScanWithoutPoints) {
  TempDir tmp;
  const LidarScan scan = read_scan({0, write_binary<float>(tmp.path / "0.bin", {}), {}});
  EXPECT_TRUE(scan.points.empty());
  EXPECT_TRUE(scan.labels.empty());
}

TEST(ScanIo, TruncatedBinIsAnErrorNamingFileAndSize) {
  TempDir tmp;
  const auto bin = write_binary<float>(tmp.path / "cut.bin", std::vector<float>(8, 1.0f), 5);  // 16*2 + 5 bytes
  const std::string message = error_of({0, bin, {}});
  EXPECT_NE(message.find("truncated"), std::string::npos) << message;
  EXPECT_NE(message.find("cut.bin"), std::string::npos) << message;
  EXPECT_NE(message.find("37"), std::string::npos) << message;
}

TEST(ScanIo, LabelCountMismatchIsAnError) {
  TempDir tmp;
  const auto bin = write_binary<float>(tmp.path / "0.bin", std::vector<float>(12, 1.0f));  // 3 points
  const auto label = write_binary<uint32_t>(tmp.path / "0.label", {1, 2});
  const std::string message = error_of({0, bin, label});
  EXPECT_NE(message.find("2 labels"), std::string::npos) << message;
  EXPECT_NE(message.find("3 points"), std::string::npos) << message;
  EXPECT_NE(error_of({0, tmp.path / "missing.bin", {}}).find("missing.bin"), std::string::npos);
}

TEST(ScanIo, NanPointsAreReturnedAsStoredAndCountedWhenDropped) {
  TempDir tmp;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const auto bin = write_binary<float>(tmp.path / "0.bin", {nan, 1, 1, 0,  /* non-finite */
                                                            0, 0, 0, 0,    /* no return */
                                                            0.1f, 0, 0, 0, /* too close */
                                                            5, 0, 0, 7});
  const auto label = write_binary<uint32_t>(tmp.path / "0.label", {1, 2, 3, 4});
  LidarScan scan = read_scan({0, bin, label});
  ASSERT_EQ(scan.points.size(), 4u);
  EXPECT_TRUE(std::isnan(scan.points[0].x()));

  const ScanFilterStats stats = drop_invalid_points(scan, 0.5f);
  EXPECT_EQ(stats.input, 4u);
  EXPECT_EQ(stats.non_finite, 1u);
  EXPECT_EQ(stats.no_return, 1u);
  EXPECT_EQ(stats.too_close, 1u);
  EXPECT_EQ(stats.kept(), 1u);
  ASSERT_EQ(scan.points.size(), 1u);
  EXPECT_EQ(scan.points[0], Vec3f(5, 0, 0));
  EXPECT_EQ(scan.intensity, std::vector<float>{7});
  EXPECT_EQ(scan.labels, std::vector<uint16_t>{4});
}

}  // namespace
}  // namespace slamvdb
