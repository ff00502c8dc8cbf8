#pragma once
// Encoders of the ROS 2 messages slamvdb writes into recordings (MCAP, `slamvdb convert`): CDR,
// little-endian (encapsulation CDR_LE, as ROS 2 publishes on x86 and ARM), and the ros2msg
// definition text of each type (with its dependencies, the form rosbag2 and MCAP carry). The
// decoders of the same messages are messages.hpp, point_cloud2.hpp and image.hpp; the tests read
// what these write back with an independent reader (@mcap/core and @foxglove's CDR reader).
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/recording/messages.hpp"

namespace slamvdb::recording {

// The ros2msg definition of `type` ("sensor_msgs/msg/PointCloud2", ...: PointCloud2,
// CompressedImage, Image, CameraInfo, tf2_msgs/msg/TFMessage, nav_msgs/msg/Odometry). Throws Error
// for another type.
const std::string& ros2_definition(std::string_view type);

// sensor_msgs/PointCloud2, unorganised (height 1): x y z float32 at 0 4 8, intensity float32 at 12
// when `intensity` is not empty, and `t` uint32 (ns since header.stamp, the scan start, as Ouster
// drivers write it) after them. `t` may be empty: every point then has t = 0.
std::vector<std::uint8_t> encode_point_cloud2(const Header& header, std::span<const Vec3f> points,
                                              std::span<const float> intensity, std::span<const std::uint32_t> t);
// sensor_msgs/CompressedImage: `format` "jpeg" or "png", the encoded bytes.
std::vector<std::uint8_t> encode_compressed_image(const Header& header, std::string_view format,
                                                  std::span<const std::uint8_t> data);
// sensor_msgs/Image mono8, `width` x `height` bytes without row padding.
std::vector<std::uint8_t> encode_mono8_image(const Header& header, std::uint32_t width, std::uint32_t height,
                                             std::span<const std::uint8_t> pixels);
std::vector<std::uint8_t> encode_camera_info(const CameraInfo& info);
// tf2_msgs/TFMessage.
std::vector<std::uint8_t> encode_tf_message(std::span<const TransformStamped> transforms);
// nav_msgs/Odometry (the twist and its covariance are written as given).
std::vector<std::uint8_t> encode_odometry(const Odometry& odometry);

}  // namespace slamvdb::recording
