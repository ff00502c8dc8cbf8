#pragma once
// LiDAR scans on disk: KITTI-style .bin (x y z intensity float32) and SemanticKITTI .label files.
#include <cstddef>
#include <cstdint>

#include "slamvdb/core/types.hpp"
#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

// Largest scan file read: 256 MiB, 16.7 million points (an OS1-128 scan has 262 144).
inline constexpr std::uint64_t kMaxScanFileBytes = std::uint64_t{256} << 20;

// Reads the scan exactly as stored, including NaN and all-zero ("no return") points; an empty
// file is a valid scan with 0 points. Throws Error on a truncated .bin, a label count mismatch,
// a file above kMaxScanFileBytes, or a path that is not a regular file (a FIFO, ...).
LidarScan read_scan(const ScanRecord& record);

struct ScanFilterStats {
  std::size_t input = 0;
  std::size_t non_finite = 0;  // a NaN or inf coordinate
  std::size_t no_return = 0;   // exactly (0, 0, 0): the sensor's marker for a missing return
  std::size_t too_close = 0;   // closer than min_range
  std::size_t kept() const { return input - non_finite - no_return - too_close; }
};

// Removes the points above (keeping intensity and labels aligned) and counts them by reason.
ScanFilterStats drop_invalid_points(LidarScan& scan, float min_range);

}  // namespace slamvdb
