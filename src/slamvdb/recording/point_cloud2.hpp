#pragma once
// sensor_msgs/PointCloud2: a view of the message (its layout checked), and the extraction of the
// points and per-point times slamvdb maps with, for any field layout and datatype.
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/recording/messages.hpp"

namespace slamvdb::recording {

// sensor_msgs/PointField datatypes.
enum class PointFieldType : std::uint8_t {
  kInt8 = 1, kUInt8 = 2, kInt16 = 3, kUInt16 = 4, kInt32 = 5, kUInt32 = 6, kFloat32 = 7, kFloat64 = 8
};
// Bytes of one value of `datatype`; 0 for a datatype outside 1..8.
std::size_t point_field_type_size(std::uint8_t datatype);

struct PointField {
  std::string name;
  std::uint32_t offset = 0;  // within a point
  std::uint8_t datatype = 0;
  std::uint32_t count = 1;
};

struct PointCloud2View {
  Header header;
  std::uint32_t height = 0, width = 0;  // unorganised clouds: height 1
  std::vector<PointField> fields;
  bool is_bigendian = false;
  std::uint32_t point_step = 0, row_step = 0;
  std::span<const std::uint8_t> data;  // into the message bytes
  bool is_dense = false;
  std::uint64_t point_count() const { return std::uint64_t{height} * width; }
  const PointField* field(std::string_view name) const;
};

// Decodes the message and checks its layout: row_step at least width * point_step, data at least
// height rows of row_step bytes (the last row may stop after its last point) and no more.
PointCloud2View decode_point_cloud2(std::span<const std::uint8_t> bytes, Serialization serialization);

// The per-point time fields drivers write, each read as seconds relative to header.stamp.
enum class PointTimeField {
  kNone,
  kT,           // `t`: ns since the scan start (Ouster; header.stamp is the scan start)
  kOffsetTime,  // `offset_time`: ns since header.stamp (Livox)
  kTime,        // `time`: s relative to header.stamp (Velodyne; may be negative)
  kTimestamp    // `timestamp`: absolute s since the epoch (Hesai, Livox-style drivers)
};
std::string_view describe(PointTimeField field);

struct CloudExtraction {
  std::size_t points = 0;
  PointTimeField time_field = PointTimeField::kNone;
  bool fast_path = false;  // float32 x, y, z in host byte order
};

// The points of `cloud` in row-major order (organised clouds row by row), x, y, z of any
// datatype converted to float. NaN points (is_dense false) are kept: callers filter and count
// them. If `times` is given it gets one time per point in seconds relative to header.stamp, from
// the first of t, offset_time, time, timestamp the cloud has, or is cleared when it has none;
// `intensity`, if given, the `intensity` field (cleared when there is none). The vectors are
// resized, their capacity reused. A cloud without x, y and z, or whose fields do not fit in a
// point, is an Error naming the field.
CloudExtraction extract_points(const PointCloud2View& cloud, std::vector<Vec3f>& points,
                               std::vector<float>* times = nullptr, std::vector<float>* intensity = nullptr);

}  // namespace slamvdb::recording
