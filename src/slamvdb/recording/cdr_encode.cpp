#include "slamvdb/recording/cdr_encode.hpp"

#include <fmt/format.h>

#include <bit>
#include <cstring>
#include <map>
#include <type_traits>

#include "slamvdb/core/error.hpp"

namespace slamvdb::recording {

// File-local helpers in a named namespace: the unity build merges the recording sources.
namespace cdr_encode_cpp {

// CDR little-endian: the 4-byte encapsulation header (CDR_LE), then every primitive aligned to its
// size relative to the end of that header; strings are a uint32 length counting a final NUL.
class CdrOut {
 public:
  CdrOut() { bytes_ = {0x00, 0x01, 0x00, 0x00}; }
  template <class T>
  void put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    align(sizeof(T));
    const std::size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &value, sizeof(T));  // little-endian hosts only (checked below)
  }
  void u8(std::uint8_t v) { put(v); }
  void u32(std::uint32_t v) { put(v); }
  void f64(double v) { put(v); }
  void string(std::string_view s) {
    u32(static_cast<std::uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
  }
  void octets(std::span<const std::uint8_t> data) {
    u32(static_cast<std::uint32_t>(data.size()));
    bytes_.insert(bytes_.end(), data.begin(), data.end());
  }
  void header(const Header& h) {
    put(static_cast<std::int32_t>(h.stamp_ns / 1'000'000'000));
    u32(static_cast<std::uint32_t>(h.stamp_ns % 1'000'000'000));
    string(h.frame_id);
  }
  void quaternion(const Pose& pose) {
    const Eigen::Quaterniond q(pose.rotation());
    for (const double v : {q.x(), q.y(), q.z(), q.w()}) f64(v);
  }
  void vector3(const Vec3d& v) {
    for (int i = 0; i < 3; ++i) f64(v[i]);
  }
  // Reserves `n` bytes for a payload (after its uint32 length) and returns where they start.
  std::uint8_t* payload(std::size_t n) {
    u32(static_cast<std::uint32_t>(n));
    const std::size_t at = bytes_.size();
    bytes_.resize(at + n);
    return bytes_.data() + at;
  }
  std::vector<std::uint8_t> take() { return std::move(bytes_); }

 private:
  void align(std::size_t n) {
    const std::size_t body = bytes_.size() - 4;
    bytes_.resize(bytes_.size() + (n - body % n) % n, 0);
  }
  std::vector<std::uint8_t> bytes_;
};

static_assert(std::endian::native == std::endian::little, "the CDR encoders write little-endian by memcpy");

const std::string kSeparator = "\n" + std::string(80, '=') + "\n";
std::string with_dependencies(const std::string& main, const std::vector<std::pair<std::string, std::string>>& deps) {
  std::string text = main;
  for (const auto& [name, definition] : deps) text += kSeparator + "MSG: " + name + "\n" + definition;
  return text;
}

std::map<std::string, std::string, std::less<>> make_definitions() {
  const std::pair<std::string, std::string> header{"std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id"};
  const std::pair<std::string, std::string> time{"builtin_interfaces/Time", "int32 sec\nuint32 nanosec"};
  const std::string vector3 = "float64 x\nfloat64 y\nfloat64 z";
  const std::string quaternion = "float64 x\nfloat64 y\nfloat64 z\nfloat64 w";
  const std::string point_field =
      "uint8 INT8    = 1\nuint8 UINT8   = 2\nuint8 INT16   = 3\nuint8 UINT16  = 4\nuint8 INT32   = 5\n"
      "uint8 UINT32  = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\nstring name\nuint32 offset\nuint8  datatype\nuint32 "
      "count";
  const std::string h = "std_msgs/Header header";
  std::map<std::string, std::string, std::less<>> d;
  d["sensor_msgs/msg/PointCloud2"] = with_dependencies(
      h + "\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\nuint32 point_step\n"
          "uint32 row_step\nuint8[] data\nbool is_dense",
      {header, time, {"sensor_msgs/PointField", point_field}});
  d["sensor_msgs/msg/CompressedImage"] = with_dependencies(h + "\nstring format\nuint8[] data", {header, time});
  d["sensor_msgs/msg/Image"] = with_dependencies(
      h + "\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data",
      {header, time});
  d["sensor_msgs/msg/CameraInfo"] = with_dependencies(
      h + "\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\n"
          "float64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi",
      {header,
       time,
       {"sensor_msgs/RegionOfInterest",
        "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify"}});
  d["tf2_msgs/msg/TFMessage"] = with_dependencies(
      "geometry_msgs/TransformStamped[] transforms",
      {{"geometry_msgs/TransformStamped", h + "\nstring child_frame_id\ngeometry_msgs/Transform transform"},
       header,
       time,
       {"geometry_msgs/Transform", "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation"},
       {"geometry_msgs/Vector3", vector3},
       {"geometry_msgs/Quaternion", quaternion}});
  d["nav_msgs/msg/Odometry"] = with_dependencies(
      h + "\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist",
      {header,
       time,
       {"geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose pose\nfloat64[36] covariance"},
       {"geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation"},
       {"geometry_msgs/Point", vector3},
       {"geometry_msgs/Quaternion", quaternion},
       {"geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist twist\nfloat64[36] covariance"},
       {"geometry_msgs/Twist", "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular"},
       {"geometry_msgs/Vector3", vector3}});
  return d;
}

}  // namespace cdr_encode_cpp

const std::string& ros2_definition(std::string_view type) {
  static const auto definitions = cdr_encode_cpp::make_definitions();
  const auto it = definitions.find(type);
  if (it == definitions.end()) throw Error(fmt::format("no ros2msg definition for message type {}", type));
  return it->second;
}

std::vector<std::uint8_t> encode_point_cloud2(const Header& header, std::span<const Vec3f> points,
                                              std::span<const float> intensity, std::span<const std::uint32_t> t) {
  const bool with_intensity = !intensity.empty();
  if (with_intensity && intensity.size() != points.size())
    throw Error(fmt::format("PointCloud2: {} intensities for {} points", intensity.size(), points.size()));
  if (!t.empty() && t.size() != points.size())
    throw Error(fmt::format("PointCloud2: {} point times for {} points", t.size(), points.size()));
  const std::uint32_t t_offset = with_intensity ? 16 : 12, step = t_offset + 4;
  cdr_encode_cpp::CdrOut o;
  o.header(header);
  o.u32(1);
  o.u32(static_cast<std::uint32_t>(points.size()));
  const auto field = [&](std::string_view name, std::uint32_t offset, std::uint8_t datatype) {
    o.string(name);
    o.u32(offset);
    o.u8(datatype);
    o.u32(1);
  };
  o.u32(with_intensity ? 5 : 4);
  field("x", 0, 7);
  field("y", 4, 7);
  field("z", 8, 7);
  if (with_intensity) field("intensity", 12, 7);
  field("t", t_offset, 6);
  o.u8(0);  // is_bigendian
  o.u32(step);
  o.u32(static_cast<std::uint32_t>(points.size() * step));
  std::uint8_t* data = o.payload(points.size() * step);
  for (std::size_t i = 0; i < points.size(); ++i, data += step) {
    std::memcpy(data, points[i].data(), 12);
    if (with_intensity) std::memcpy(data + 12, &intensity[i], 4);
    const std::uint32_t time = t.empty() ? 0 : t[i];
    std::memcpy(data + t_offset, &time, 4);
  }
  o.u8(1);  // is_dense: NaN points are written as they are, and counted by the readers
  return o.take();
}

std::vector<std::uint8_t> encode_compressed_image(const Header& header, std::string_view format,
                                                  std::span<const std::uint8_t> data) {
  cdr_encode_cpp::CdrOut o;
  o.header(header);
  o.string(format);
  o.octets(data);
  return o.take();
}

std::vector<std::uint8_t> encode_mono8_image(const Header& header, std::uint32_t width, std::uint32_t height,
                                             std::span<const std::uint8_t> pixels) {
  if (pixels.size() != std::size_t{width} * height)
    throw Error(fmt::format("Image: {} bytes for a {}x{} mono8 image", pixels.size(), width, height));
  cdr_encode_cpp::CdrOut o;
  o.header(header);
  o.u32(height);
  o.u32(width);
  o.string("mono8");
  o.u8(0);
  o.u32(width);
  o.octets(pixels);
  return o.take();
}

std::vector<std::uint8_t> encode_camera_info(const CameraInfo& info) {
  cdr_encode_cpp::CdrOut o;
  o.header(info.header);
  o.u32(info.height);
  o.u32(info.width);
  o.string(info.distortion_model);
  o.u32(static_cast<std::uint32_t>(info.D.size()));
  for (const double v : info.D) o.f64(v);
  for (const double v : info.K) o.f64(v);
  for (const double v : info.R) o.f64(v);
  for (const double v : info.P) o.f64(v);
  o.u32(info.binning_x);
  o.u32(info.binning_y);
  for (const std::uint32_t v : {info.roi_x_offset, info.roi_y_offset, info.roi_height, info.roi_width}) o.u32(v);
  o.u8(info.roi_do_rectify ? 1 : 0);
  return o.take();
}

std::vector<std::uint8_t> encode_tf_message(std::span<const TransformStamped> transforms) {
  cdr_encode_cpp::CdrOut o;
  o.u32(static_cast<std::uint32_t>(transforms.size()));
  for (const TransformStamped& t : transforms) {
    o.header(t.header);
    o.string(t.child_frame_id);
    o.vector3(t.T_parent_child.translation());
    o.quaternion(t.T_parent_child);
  }
  return o.take();
}

std::vector<std::uint8_t> encode_odometry(const Odometry& odometry) {
  cdr_encode_cpp::CdrOut o;
  o.header(odometry.header);
  o.string(odometry.child_frame_id);
  o.vector3(odometry.T_frame_child.translation());
  o.quaternion(odometry.T_frame_child);
  for (const double v : odometry.pose_covariance) o.f64(v);
  o.vector3(odometry.linear_velocity);
  o.vector3(odometry.angular_velocity);
  for (const double v : odometry.twist_covariance) o.f64(v);
  return o.take();
}

}  // namespace slamvdb::recording
