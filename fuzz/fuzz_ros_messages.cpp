// The ROS message decoders in both serializations. The first byte picks the decoder (low four
// bits, modulo 9) and the serialization (bit 4: 0 ROS 1, 1 CDR); the rest is the message. Decoded
// clouds and images are converted too, as their callers do.
#include <cstdint>
#include <vector>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/image.hpp"
#include "slamvdb/recording/messages.hpp"
#include "slamvdb/recording/point_cloud2.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace slamvdb::recording;
  if (size == 0) return 0;
  const int decoder = (data[0] & 0x0f) % 9;
  const Serialization serialization = (data[0] & 0x10) ? Serialization::kCdr : Serialization::kRos1;
  const std::vector<std::uint8_t> bytes(data + 1, data + size);  // exactly sized: overreads are caught
  try {
    switch (decoder) {
      case 0: {
        const PointCloud2View cloud = decode_point_cloud2(bytes, serialization);
        std::vector<slamvdb::Vec3f> points;
        std::vector<float> times, intensity;
        const CloudExtraction e = extract_points(cloud, points, &times, &intensity);
        if (points.size() != cloud.point_count() || (!times.empty() && times.size() != points.size()))
          __builtin_trap();
        (void)e;
        break;
      }
      case 1: {
        const ImageView image = decode_image(bytes, serialization);
        std::vector<std::uint8_t> out;
        try {
          image_to_rgb8(image, out);
          if (out.size() != std::size_t{image.width} * image.height * 3) __builtin_trap();
        } catch (const slamvdb::Error&) {
        }
        image_to_mono8(image, out);
        break;
      }
      case 2: (void)decode_compressed_image(bytes, serialization); break;
      case 3: (void)decode_camera_info(bytes, serialization); break;
      case 4: (void)decode_tf_message(bytes, serialization); break;
      case 5: (void)decode_odometry(bytes, serialization); break;
      case 6: (void)decode_pose_stamped(bytes, serialization); break;
      case 7: (void)decode_transform_stamped(bytes, serialization); break;
      default: (void)decode_header(bytes, serialization); break;
    }
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
