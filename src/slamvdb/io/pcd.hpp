#pragma once
// Point Cloud Data (.pcd) files as PCL writes them: DATA ascii, binary and binary_compressed (LZF,
// via Debian's liblzf, the same format PCL uses), any field set that contains x y z, fields of any
// PCD type (F4/F8, I1..I8, U1..U8) and COUNT, padding fields included. Written by hand because
// PCL itself is far too large a dependency for one file format.
#include <filesystem>
#include <vector>

#include "slamvdb/core/types.hpp"

namespace slamvdb {

struct PcdCloud {
  std::vector<Vec3f> points;     // x y z as stored (NaN kept: callers count and drop them)
  std::vector<float> intensity;  // from a field named intensity / reflectivity; else empty
  std::vector<float> time;       // per-point time from a field named t / time / timestamp; else empty
};

// Throws Error naming the file on a malformed header, an unsupported type, or truncated data.
PcdCloud read_pcd(const std::filesystem::path& file);

enum class PcdEncoding { kAscii, kBinary, kBinaryCompressed };
// Fields x y z (F4), then intensity and t (F4) when present. Throws Error naming the file.
void write_pcd(const std::filesystem::path& file, const PcdCloud& cloud, PcdEncoding encoding = PcdEncoding::kBinary);

}  // namespace slamvdb
