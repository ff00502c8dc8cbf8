// Scan .bin (x y z intensity float32) and .label (uint32) files: the first two bytes say where
// the input splits into the two files (no split: a scan without labels).
#include <cstring>

#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/scan_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 2) return 0;
  const std::size_t split = std::min<std::size_t>(size - 2, (std::size_t{data[0]} << 8) | data[1]);
  const bool with_labels = split < size - 2;
  try {
    slamvdb::ScanRecord record;
    record.points = slamvdb::fuzz::write_input(data + 2, split, "000000.bin");
    if (with_labels) record.labels = slamvdb::fuzz::write_input(data + 2 + split, size - 2 - split, "000000.label");
    slamvdb::LidarScan scan = slamvdb::read_scan(record);
    const auto stats = slamvdb::drop_invalid_points(scan, 0.3f);
    if (stats.kept() != scan.points.size()) __builtin_trap();
    for (const auto& p : scan.points)
      if (!p.allFinite()) __builtin_trap();  // the filter must leave only finite points
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
