#pragma once
// Decoders of the ROS messages slamvdb uses, from their bytes in either serialization (ROS 1 or
// CDR); they never know which container the bytes came from. A message that does not decode is an
// Error naming the type, the field and the byte offset (the caller adds the topic and the message
// index). PointCloud2 is in point_cloud2.hpp, Image in image.hpp.
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

class WireReader;

// The message types slamvdb decodes, by their normalised (ROS 1) name.
enum class MessageKind {
  kUnknown,
  kPointCloud2,      // sensor_msgs/PointCloud2
  kImage,            // sensor_msgs/Image
  kCompressedImage,  // sensor_msgs/CompressedImage
  kCameraInfo,       // sensor_msgs/CameraInfo
  kTf,               // tf2_msgs/TFMessage or ROS 1's tf/tfMessage
  kOdometry,         // nav_msgs/Odometry
  kPoseStamped,      // geometry_msgs/PoseStamped
  kTransformStamped  // geometry_msgs/TransformStamped
};
MessageKind message_kind(std::string_view type);

// std_msgs/Header. ROS 2's has no seq (0 here).
struct Header {
  std::uint32_t seq = 0;
  std::int64_t stamp_ns = 0;  // since the Unix epoch
  std::string frame_id;
  double stamp_seconds() const { return static_cast<double>(stamp_ns) * 1e-9; }
};
// Reads a Header field of an enclosing message (errors name "header.*").
Header read_header(WireReader& reader);
Header decode_header(std::span<const std::uint8_t> bytes, Serialization serialization);

// sensor_msgs/CompressedImage: the encoded bytes (jpeg, png, ...) as a view into the message.
struct CompressedImageView {
  Header header;
  std::string format;  // "jpeg", "png", or forms like "bgr8; jpeg compressed bgr8"
  std::span<const std::uint8_t> data;
};
CompressedImageView decode_compressed_image(std::span<const std::uint8_t> bytes, Serialization serialization);

// sensor_msgs/CameraInfo. The caller decides which distortion models it accepts (slamvdb:
// plumb_bob, or none with all-zero D) and names the model when it refuses one.
struct CameraInfo {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string distortion_model;
  std::vector<double> D;
  std::array<double, 9> K{}, R{};  // row-major 3 x 3
  std::array<double, 12> P{};      // row-major 3 x 4
  std::uint32_t binning_x = 0, binning_y = 0;
  std::uint32_t roi_x_offset = 0, roi_y_offset = 0, roi_height = 0, roi_width = 0;
  bool roi_do_rectify = false;
};
CameraInfo decode_camera_info(std::span<const std::uint8_t> bytes, Serialization serialization);

// geometry_msgs/TransformStamped: the pose of child_frame_id in header.frame_id (it maps points
// from the child frame into the parent frame). The quaternion is normalised; a zero or non-finite
// one is an Error.
struct TransformStamped {
  Header header;  // frame_id: the parent frame
  std::string child_frame_id;
  Pose T_parent_child = Pose::Identity();
};
TransformStamped decode_transform_stamped(std::span<const std::uint8_t> bytes, Serialization serialization);

// tf2_msgs/TFMessage and tf/tfMessage (the same layout: TransformStamped[] transforms).
std::vector<TransformStamped> decode_tf_message(std::span<const std::uint8_t> bytes, Serialization serialization);

// nav_msgs/Odometry: pose of child_frame_id in header.frame_id, and its twist in the child frame.
struct Odometry {
  Header header;
  std::string child_frame_id;
  Pose T_frame_child = Pose::Identity();
  std::array<double, 36> pose_covariance{};
  Vec3d linear_velocity = Vec3d::Zero(), angular_velocity = Vec3d::Zero();
  std::array<double, 36> twist_covariance{};
};
Odometry decode_odometry(std::span<const std::uint8_t> bytes, Serialization serialization);

// geometry_msgs/PoseStamped: a pose in header.frame_id.
struct PoseStamped {
  Header header;
  Pose T_frame_pose = Pose::Identity();
};
PoseStamped decode_pose_stamped(std::span<const std::uint8_t> bytes, Serialization serialization);

}  // namespace slamvdb::recording
