#include "slamvdb/recording/point_cloud2.hpp"

#include <fmt/format.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <optional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/wire.hpp"

namespace slamvdb::recording {

namespace point_cloud2_detail {

constexpr std::string_view kCloudType = "sensor_msgs/PointCloud2";
// The fewest bytes a PointField takes in either serialization (empty name, offset, datatype, count).
constexpr std::size_t kMinPointFieldBytes = 13;

// What is wrong with the cloud's geometry, or "" (the field it concerns in `field`).
std::string cloud_layout_problem(const PointCloud2View& c, std::string_view& field) {
  const std::uint64_t points = c.point_count();
  const std::uint64_t row_bytes = std::uint64_t{c.width} * c.point_step;
  if (points > 0 && c.point_step == 0) {
    field = "point_step";
    return fmt::format("is 0 for {} x {} points", c.height, c.width);
  }
  if (c.height > 0 && row_bytes > c.row_step) {
    field = "row_step";
    return fmt::format("{} disagrees with width {} x point_step {} = {} bytes", c.row_step, c.width, c.point_step,
                       row_bytes);
  }
  const std::uint64_t full = std::uint64_t{c.height} * c.row_step;
  const std::uint64_t needed = c.height == 0 ? 0 : full - c.row_step + row_bytes;  // the last row may be unpadded
  if (c.data.size() < needed || c.data.size() > full) {
    field = "data";
    return fmt::format("has {} bytes where height {} x row_step {} = {} bytes are expected", c.data.size(), c.height,
                       c.row_step, full);
  }
  return {};
}

template <typename T>
T load_value(const std::uint8_t* p, bool swap) {
  if constexpr (sizeof(T) == 1) {
    (void)swap;
    return static_cast<T>(*p);
  } else {
    using U = std::conditional_t<sizeof(T) == 2, std::uint16_t, std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>;
    U bits;
    std::memcpy(&bits, p, sizeof(U));
    if (swap) {
      if constexpr (sizeof(U) == 2) bits = __builtin_bswap16(bits);
      if constexpr (sizeof(U) == 4) bits = __builtin_bswap32(bits);
      if constexpr (sizeof(U) == 8) bits = __builtin_bswap64(bits);
    }
    return std::bit_cast<T>(bits);
  }
}

template <typename T, bool kSwap>
double load_as_double(const std::uint8_t* p) {
  return static_cast<double>(load_value<T>(p, kSwap));
}

using Loader = double (*)(const std::uint8_t*);

template <bool kSwap>
Loader loader_of(std::uint8_t datatype) {
  switch (static_cast<PointFieldType>(datatype)) {
    case PointFieldType::kInt8: return &load_as_double<std::int8_t, kSwap>;
    case PointFieldType::kUInt8: return &load_as_double<std::uint8_t, kSwap>;
    case PointFieldType::kInt16: return &load_as_double<std::int16_t, kSwap>;
    case PointFieldType::kUInt16: return &load_as_double<std::uint16_t, kSwap>;
    case PointFieldType::kInt32: return &load_as_double<std::int32_t, kSwap>;
    case PointFieldType::kUInt32: return &load_as_double<std::uint32_t, kSwap>;
    case PointFieldType::kFloat32: return &load_as_double<float, kSwap>;
    case PointFieldType::kFloat64: return &load_as_double<double, kSwap>;
  }
  return nullptr;
}

// How one scalar of every point is read: at `offset`, by `load`, then value * scale - bias.
struct Component {
  std::uint32_t offset = 0;
  Loader load = nullptr;
  double scale = 1.0, bias = 0.0;
  const PointField* field = nullptr;
};

std::string cloud_field_names(const PointCloud2View& c) {
  std::string names;
  for (const PointField& f : c.fields) names += (names.empty() ? "" : ", ") + f.name;
  return names.empty() ? "none" : names;
}

Component component(const PointCloud2View& c, const PointField& f) {
  const std::size_t size = point_field_type_size(f.datatype);
  if (size == 0)
    throw Error(fmt::format("{}: field {} has datatype {}, not one of INT8 (1) .. FLOAT64 (8)", kCloudType, f.name,
                            f.datatype));
  if (std::uint64_t{f.offset} + size > c.point_step)
    throw Error(fmt::format("{}: field {} ({} bytes at offset {}) does not fit in point_step {}", kCloudType, f.name, size,
                            f.offset, c.point_step));
  const bool swap = c.is_bigendian != (std::endian::native == std::endian::big);
  return {f.offset, swap ? loader_of<true>(f.datatype) : loader_of<false>(f.datatype), 1.0, 0.0, &f};
}

// The time field and how its values become seconds relative to header.stamp.
std::optional<std::pair<PointTimeField, Component>> time_component(const PointCloud2View& c) {
  constexpr std::pair<std::string_view, PointTimeField> kNames[] = {{"t", PointTimeField::kT},
                                                                    {"offset_time", PointTimeField::kOffsetTime},
                                                                    {"time", PointTimeField::kTime},
                                                                    {"timestamp", PointTimeField::kTimestamp}};
  for (const auto& [name, kind] : kNames) {
    const PointField* f = c.field(name);
    if (!f) continue;
    Component time = component(c, *f);
    if (kind == PointTimeField::kT || kind == PointTimeField::kOffsetTime) time.scale = 1e-9;
    // Absolute seconds: whole seconds first, exactly, so that the fraction keeps its precision.
    if (kind == PointTimeField::kTimestamp) time.bias = static_cast<double>(c.header.stamp_ns / 1'000'000'000);
    return std::pair{kind, time};
  }
  return std::nullopt;
}

template <typename T, bool kSwap>
void read_column_as(const std::uint8_t* p, std::uint32_t n, std::uint32_t step, double scale, double bias,
                    double bias2, float* out) {
  for (std::uint32_t i = 0; i < n; ++i, p += step)
    out[i] = static_cast<float>((static_cast<double>(load_value<T>(p, kSwap)) * scale - bias) - bias2);
}

template <bool kSwap>
bool read_column_direct(const Component& c, const std::uint8_t* p, std::uint32_t n, std::uint32_t step, double bias2,
                        float* out) {
  switch (static_cast<PointFieldType>(c.field->datatype)) {
    case PointFieldType::kUInt32: read_column_as<std::uint32_t, kSwap>(p, n, step, c.scale, c.bias, bias2, out); return true;
    case PointFieldType::kFloat32: read_column_as<float, kSwap>(p, n, step, c.scale, c.bias, bias2, out); return true;
    case PointFieldType::kFloat64: read_column_as<double, kSwap>(p, n, step, c.scale, c.bias, bias2, out); return true;
    default: return false;
  }
}

// One scalar of each of a row's `n` points into out: value * scale - bias - bias2. The types
// per-point times and intensities come in are read without a call per point (the common layouts'
// speed depends on it); the others through the component's loader.
void read_column(const Component& c, const std::uint8_t* row, std::uint32_t n, std::uint32_t step, bool swap,
                 double bias2, float* out) {
  const std::uint8_t* p = row + c.offset;
  if (swap ? read_column_direct<true>(c, p, n, step, bias2, out) : read_column_direct<false>(c, p, n, step, bias2, out))
    return;
  for (std::uint32_t i = 0; i < n; ++i, p += step)
    out[i] = static_cast<float>((c.load(p) * c.scale - c.bias) - bias2);
}

// x, y, z of one datatype T for a row's `n` points.
template <typename T, bool kSwap>
void read_xyz_as(const std::uint8_t* p, std::uint32_t n, std::uint32_t step, const std::uint32_t (&offset)[3],
                 Vec3f* out) {
  for (std::uint32_t i = 0; i < n; ++i, p += step)
    out[i] = Vec3f(static_cast<float>(load_value<T>(p + offset[0], kSwap)),
                   static_cast<float>(load_value<T>(p + offset[1], kSwap)),
                   static_cast<float>(load_value<T>(p + offset[2], kSwap)));
}

template <bool kSwap>
void read_xyz_same_type(std::uint8_t datatype, const std::uint8_t* p, std::uint32_t n, std::uint32_t step,
                        const std::uint32_t (&offset)[3], Vec3f* out) {
  switch (static_cast<PointFieldType>(datatype)) {
    case PointFieldType::kInt8: return read_xyz_as<std::int8_t, kSwap>(p, n, step, offset, out);
    case PointFieldType::kUInt8: return read_xyz_as<std::uint8_t, kSwap>(p, n, step, offset, out);
    case PointFieldType::kInt16: return read_xyz_as<std::int16_t, kSwap>(p, n, step, offset, out);
    case PointFieldType::kUInt16: return read_xyz_as<std::uint16_t, kSwap>(p, n, step, offset, out);
    case PointFieldType::kInt32: return read_xyz_as<std::int32_t, kSwap>(p, n, step, offset, out);
    case PointFieldType::kUInt32: return read_xyz_as<std::uint32_t, kSwap>(p, n, step, offset, out);
    case PointFieldType::kFloat32: return read_xyz_as<float, kSwap>(p, n, step, offset, out);
    case PointFieldType::kFloat64: return read_xyz_as<double, kSwap>(p, n, step, offset, out);
  }
}

}  // namespace point_cloud2_detail

std::size_t point_field_type_size(std::uint8_t datatype) {
  constexpr std::size_t kSizes[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
  return datatype < std::size(kSizes) ? kSizes[datatype] : 0;
}

const PointField* PointCloud2View::field(std::string_view name) const {
  for (const PointField& f : fields)
    if (f.name == name) return &f;
  return nullptr;
}

std::string_view describe(PointTimeField field) {
  switch (field) {
    case PointTimeField::kNone: return "none";
    case PointTimeField::kT: return "t (uint32 ns from the scan start)";
    case PointTimeField::kOffsetTime: return "offset_time (ns from the header stamp)";
    case PointTimeField::kTime: return "time (s relative to the header stamp)";
    case PointTimeField::kTimestamp: return "timestamp (absolute s)";
  }
  return "?";
}

PointCloud2View decode_point_cloud2(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace point_cloud2_detail;
  WireReader reader(bytes, serialization, kCloudType);
  PointCloud2View c;
  c.header = read_header(reader);
  c.height = reader.u32("height");
  c.width = reader.u32("width");
  c.fields.resize(reader.sequence_length("fields", kMinPointFieldBytes));
  for (std::size_t i = 0; i < c.fields.size(); ++i) {
    const WireReader::Scope scope(reader, "fields", static_cast<std::int64_t>(i));
    PointField& f = c.fields[i];
    f.name = reader.string("name");
    f.offset = reader.u32("offset");
    f.datatype = reader.u8("datatype");
    f.count = reader.u32("count");
  }
  c.is_bigendian = reader.boolean("is_bigendian");
  const std::size_t point_step_at = reader.offset();
  c.point_step = reader.u32("point_step");
  const std::size_t row_step_at = reader.offset();
  c.row_step = reader.u32("row_step");
  const std::size_t data_at = reader.offset();
  c.data = reader.byte_sequence("data");
  c.is_dense = reader.boolean("is_dense");
  reader.expect_end();
  std::string_view field;
  if (const std::string problem = cloud_layout_problem(c, field); !problem.empty())
    reader.fail_at(field == "data" ? data_at : field == "row_step" ? row_step_at : point_step_at, field, problem);
  return c;
}

CloudExtraction extract_points(const PointCloud2View& cloud, std::vector<Vec3f>& points, std::vector<float>* times,
                               std::vector<float>* intensity) {
  using namespace point_cloud2_detail;
  std::string_view bad_field;
  if (const std::string problem = cloud_layout_problem(cloud, bad_field); !problem.empty())
    throw Error(fmt::format("{}: field {} {}", kCloudType, bad_field, problem));
  Component xyz[3];
  for (int axis = 0; axis < 3; ++axis) {
    const char* name = axis == 0 ? "x" : axis == 1 ? "y" : "z";
    const PointField* f = cloud.field(name);
    if (!f) throw Error(fmt::format("{}: has no field {} (its fields: {})", kCloudType, name, cloud_field_names(cloud)));
    xyz[axis] = component(cloud, *f);
  }
  CloudExtraction result;
  result.points = static_cast<std::size_t>(cloud.point_count());
  std::optional<Component> time, value;
  if (times) {
    if (auto found = time_component(cloud)) {
      result.time_field = found->first;
      time = found->second;
    }
  }
  if (intensity)
    if (const PointField* f = cloud.field("intensity")) value = component(cloud, *f);

  points.resize(result.points);
  if (times) times->resize(time ? result.points : 0);
  if (intensity) intensity->resize(value ? result.points : 0);
  const double time_bias_fraction =
      result.time_field == PointTimeField::kTimestamp ? static_cast<double>(cloud.header.stamp_ns % 1'000'000'000) * 1e-9
                                                      : 0.0;

  const bool swap = cloud.is_bigendian != (std::endian::native == std::endian::big);
  const std::uint8_t datatype = xyz[0].field->datatype;
  const bool same_type = xyz[1].field->datatype == datatype && xyz[2].field->datatype == datatype;
  result.fast_path = !swap && same_type && datatype == static_cast<std::uint8_t>(PointFieldType::kFloat32);
  const std::uint32_t offset[3] = {xyz[0].offset, xyz[1].offset, xyz[2].offset};
  for (std::uint32_t row = 0; row < cloud.height; ++row) {
    const std::uint8_t* p = cloud.data.data() + std::size_t{row} * cloud.row_step;
    const std::size_t first = std::size_t{row} * cloud.width;
    // Each quantity in its own pass over the row (it stays in cache), the types known at compile
    // time when x, y and z share one.
    if (same_type && swap) {
      read_xyz_same_type<true>(datatype, p, cloud.width, cloud.point_step, offset, points.data() + first);
    } else if (same_type) {
      read_xyz_same_type<false>(datatype, p, cloud.width, cloud.point_step, offset, points.data() + first);
    } else {
      for (std::uint32_t col = 0; col < cloud.width; ++col) {
        const std::uint8_t* q = p + std::size_t{col} * cloud.point_step;
        points[first + col] = Vec3f(static_cast<float>(xyz[0].load(q + offset[0])),
                                    static_cast<float>(xyz[1].load(q + offset[1])),
                                    static_cast<float>(xyz[2].load(q + offset[2])));
      }
    }
    if (time)
      read_column(*time, p, cloud.width, cloud.point_step, swap, time_bias_fraction, times->data() + first);
    if (value) read_column(*value, p, cloud.width, cloud.point_step, swap, 0.0, intensity->data() + first);
  }
  return result;
}

}  // namespace slamvdb::recording
