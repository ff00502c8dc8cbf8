#include "slamvdb/recording/messages.hpp"

#include <fmt/format.h>

#include <cmath>

#include "slamvdb/recording/wire.hpp"

namespace slamvdb::recording {

namespace messages_detail {

// The fewest bytes a TransformStamped takes (header with empty frame id, empty child frame id,
// 7 float64), a bound for the count of TFMessage's sequence.
constexpr std::size_t kMinTransformStampedBytes = 64;

// A position must be finite; a velocity may be NaN (drivers write NaN for "unknown").
Vec3d read_vector3(WireReader& reader, std::string_view name, bool require_finite = true) {
  const WireReader::Scope scope(reader, name);
  Vec3d v;
  v.x() = reader.f64("x");
  v.y() = reader.f64("y");
  v.z() = reader.f64("z");
  if (require_finite && !v.allFinite()) reader.fail("z", fmt::format("({}, {}, {}) is not finite", v.x(), v.y(), v.z()));
  return v;
}

Eigen::Quaterniond read_quaternion(WireReader& reader, std::string_view name) {
  const WireReader::Scope scope(reader, name);
  const double x = reader.f64("x"), y = reader.f64("y"), z = reader.f64("z"), w = reader.f64("w");
  const double norm = std::sqrt(x * x + y * y + z * z + w * w);
  if (!std::isfinite(norm) || norm < 1e-6)
    reader.fail("w", fmt::format("quaternion (x {}, y {}, z {}, w {}) is not a rotation (its norm is {})", x, y, z, w,
                                 norm));
  return Eigen::Quaterniond(w / norm, x / norm, y / norm, z / norm);
}

Pose make_pose(const Vec3d& translation, const Eigen::Quaterniond& rotation) {
  Pose T = Pose::Identity();
  T.linear() = rotation.toRotationMatrix();
  T.translation() = translation;
  return T;
}

// geometry_msgs/Pose: Point position, Quaternion orientation.
Pose read_pose(WireReader& reader, std::string_view name) {
  const WireReader::Scope scope(reader, name);
  const Vec3d position = read_vector3(reader, "position");
  return make_pose(position, read_quaternion(reader, "orientation"));
}

template <std::size_t N>
void read_f64_array(WireReader& reader, std::string_view field, std::array<double, N>& out) {
  reader.f64_array(field, out);
}

TransformStamped read_transform_stamped(WireReader& reader) {
  TransformStamped t;
  t.header = read_header(reader);
  t.child_frame_id = reader.string("child_frame_id");
  const WireReader::Scope scope(reader, "transform");
  const Vec3d translation = read_vector3(reader, "translation");
  t.T_parent_child = make_pose(translation, read_quaternion(reader, "rotation"));
  return t;
}

}  // namespace messages_detail

MessageKind message_kind(std::string_view type) {
  if (type == "sensor_msgs/PointCloud2") return MessageKind::kPointCloud2;
  if (type == "sensor_msgs/Image") return MessageKind::kImage;
  if (type == "sensor_msgs/CompressedImage") return MessageKind::kCompressedImage;
  if (type == "sensor_msgs/CameraInfo") return MessageKind::kCameraInfo;
  if (type == "tf2_msgs/TFMessage" || type == "tf/tfMessage") return MessageKind::kTf;
  if (type == "nav_msgs/Odometry") return MessageKind::kOdometry;
  if (type == "geometry_msgs/PoseStamped") return MessageKind::kPoseStamped;
  if (type == "geometry_msgs/TransformStamped") return MessageKind::kTransformStamped;
  return MessageKind::kUnknown;
}

Header read_header(WireReader& reader) {
  const WireReader::Scope scope(reader, "header");
  Header h;
  if (reader.serialization() == Serialization::kRos1) h.seq = reader.u32("seq");
  h.stamp_ns = reader.time_ns("stamp");
  h.frame_id = reader.string("frame_id");
  return h;
}

Header decode_header(std::span<const std::uint8_t> bytes, Serialization serialization) {
  WireReader reader(bytes, serialization, "std_msgs/Header");
  Header h;
  if (serialization == Serialization::kRos1) h.seq = reader.u32("seq");
  h.stamp_ns = reader.time_ns("stamp");
  h.frame_id = reader.string("frame_id");
  reader.expect_end();
  return h;
}

CompressedImageView decode_compressed_image(std::span<const std::uint8_t> bytes, Serialization serialization) {
  WireReader reader(bytes, serialization, "sensor_msgs/CompressedImage");
  CompressedImageView image;
  image.header = read_header(reader);
  image.format = reader.string("format");
  image.data = reader.byte_sequence("data");
  reader.expect_end();
  return image;
}

CameraInfo decode_camera_info(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace messages_detail;
  WireReader reader(bytes, serialization, "sensor_msgs/CameraInfo");
  CameraInfo info;
  info.header = read_header(reader);
  info.height = reader.u32("height");
  info.width = reader.u32("width");
  info.distortion_model = reader.string("distortion_model");
  info.D.resize(reader.sequence_length("D", sizeof(double)));
  reader.f64_array("D", info.D);
  read_f64_array(reader, "K", info.K);
  read_f64_array(reader, "R", info.R);
  read_f64_array(reader, "P", info.P);
  info.binning_x = reader.u32("binning_x");
  info.binning_y = reader.u32("binning_y");
  {
    const WireReader::Scope scope(reader, "roi");
    info.roi_x_offset = reader.u32("x_offset");
    info.roi_y_offset = reader.u32("y_offset");
    info.roi_height = reader.u32("height");
    info.roi_width = reader.u32("width");
    info.roi_do_rectify = reader.boolean("do_rectify");
  }
  reader.expect_end();
  return info;
}

TransformStamped decode_transform_stamped(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace messages_detail;
  WireReader reader(bytes, serialization, "geometry_msgs/TransformStamped");
  TransformStamped t = read_transform_stamped(reader);
  reader.expect_end();
  return t;
}

std::vector<TransformStamped> decode_tf_message(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace messages_detail;
  WireReader reader(bytes, serialization, "tf2_msgs/TFMessage");
  const std::uint32_t count = reader.sequence_length("transforms", kMinTransformStampedBytes);
  std::vector<TransformStamped> transforms;
  transforms.reserve(count);
  for (std::uint32_t i = 0; i < count; ++i) {
    const WireReader::Scope scope(reader, "transforms", i);
    transforms.push_back(read_transform_stamped(reader));
  }
  reader.expect_end();
  return transforms;
}

Odometry decode_odometry(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace messages_detail;
  WireReader reader(bytes, serialization, "nav_msgs/Odometry");
  Odometry odometry;
  odometry.header = read_header(reader);
  odometry.child_frame_id = reader.string("child_frame_id");
  {
    const WireReader::Scope scope(reader, "pose");
    odometry.T_frame_child = read_pose(reader, "pose");
    read_f64_array(reader, "covariance", odometry.pose_covariance);
  }
  {
    const WireReader::Scope scope(reader, "twist");
    const WireReader::Scope twist(reader, "twist");
    odometry.linear_velocity = read_vector3(reader, "linear", false);
    odometry.angular_velocity = read_vector3(reader, "angular", false);
  }
  {
    const WireReader::Scope scope(reader, "twist");
    read_f64_array(reader, "covariance", odometry.twist_covariance);
  }
  reader.expect_end();
  return odometry;
}

PoseStamped decode_pose_stamped(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace messages_detail;
  WireReader reader(bytes, serialization, "geometry_msgs/PoseStamped");
  PoseStamped pose;
  pose.header = read_header(reader);
  pose.T_frame_pose = read_pose(reader, "pose");
  reader.expect_end();
  return pose;
}

}  // namespace slamvdb::recording
