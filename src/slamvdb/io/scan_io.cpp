#include "slamvdb/io/scan_io.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <bit>
#include <cmath>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb {

namespace {
template <typename T>
std::vector<T> read_records(const std::filesystem::path& path, std::size_t record_bytes, const char* what) {
  RegularFile file(path, fmt::format("{} file", what));
  const std::uint64_t bytes = file.size();
  if (bytes > kMaxScanFileBytes)
    throw Error(fmt::format("{} file {} is {} bytes, more than the {} bytes ({} points) a scan may have", what, path,
                            bytes, kMaxScanFileBytes, kMaxScanFileBytes / 16));
  if (bytes % record_bytes != 0)
    throw Error(fmt::format("{} file {} is truncated: {} bytes is not a multiple of {} bytes per point", what, path,
                            bytes, record_bytes));
  std::vector<T> values(static_cast<std::size_t>(bytes) / sizeof(T));
  file.read_exact(values.data(), static_cast<std::size_t>(bytes));
  return values;
}
}  // namespace

LidarScan read_scan(const ScanRecord& record) {
  static_assert(sizeof(float) == 4 && std::endian::native == std::endian::little,
                "scan files are little-endian float32");
  const auto raw = read_records<float>(record.points, 16, "scan");
  const std::size_t n = raw.size() / 4;
  LidarScan scan;
  scan.stamp = record.stamp;
  scan.points.resize(n);
  scan.intensity.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    scan.points[i] = Vec3f(raw[4 * i], raw[4 * i + 1], raw[4 * i + 2]);
    scan.intensity[i] = raw[4 * i + 3];
  }
  if (!record.labels.empty()) {
    const auto labels = read_records<uint32_t>(record.labels, 4, "label");
    if (labels.size() != n)
      throw Error(fmt::format("label file {} has {} labels but scan {} has {} points", record.labels, labels.size(),
                              record.points, n));
    scan.labels.resize(n);
    for (std::size_t i = 0; i < n; ++i) scan.labels[i] = static_cast<uint16_t>(labels[i] & 0xffffu);
  }
  return scan;
}

ScanFilterStats drop_invalid_points(LidarScan& scan, float min_range) {
  ScanFilterStats stats;
  stats.input = scan.points.size();
  const bool has_intensity = !scan.intensity.empty(), has_labels = !scan.labels.empty();
  std::size_t out = 0;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    const Vec3f& p = scan.points[i];
    if (!p.allFinite()) {
      ++stats.non_finite;
      continue;
    }
    if (p.isZero(0.0f)) {
      ++stats.no_return;
      continue;
    }
    if (p.norm() < min_range) {
      ++stats.too_close;
      continue;
    }
    scan.points[out] = p;
    if (has_intensity) scan.intensity[out] = scan.intensity[i];
    if (has_labels) scan.labels[out] = scan.labels[i];
    ++out;
  }
  scan.points.resize(out);
  if (has_intensity) scan.intensity.resize(out);
  if (has_labels) scan.labels.resize(out);
  return stats;
}

}  // namespace slamvdb
