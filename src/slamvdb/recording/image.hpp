#pragma once
// sensor_msgs/Image: a view of the message (its layout checked for the encodings slamvdb reads)
// and conversions into the caller's buffers: packed RGB8 for cameras, mono8 for label images.
// Compressed images (jpeg, png) are decoded by io/image_io, not here.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "slamvdb/recording/messages.hpp"

namespace slamvdb::recording {

struct ImageView {
  Header header;
  std::uint32_t height = 0, width = 0;
  std::string encoding;
  bool is_bigendian = false;  // of mono16 values
  std::uint32_t step = 0;     // bytes per row, at least width * bytes per pixel (row padding)
  std::span<const std::uint8_t> data;
};

// Bytes per pixel of the encodings slamvdb reads (rgb8, bgr8, rgba8, bgra8, mono8 and its alias
// 8UC1, mono16 and 16UC1); 0 for any other encoding.
std::size_t image_bytes_per_pixel(std::string_view encoding);

// Decodes the message; for the encodings slamvdb reads, checks step against width and data
// against height x step (the last row may stop after its last pixel). Other encodings (bayer,
// yuv422, 32FC1, ...) decode, and the conversions refuse them naming the encoding.
ImageView decode_image(std::span<const std::uint8_t> bytes, Serialization serialization);

// Packed RGB, 3 x width x height bytes, into `rgb` (resized, capacity reused). mono8 is repeated
// into the three channels, mono16 scaled by 1/256; alpha is dropped.
void image_to_rgb8(const ImageView& image, std::vector<std::uint8_t>& rgb);

// One byte per pixel, width x height, into `mono` (resized): class ids of a label image. mono16
// values above 255 are an Error naming the pixel; colour encodings are an Error.
void image_to_mono8(const ImageView& image, std::vector<std::uint8_t>& mono);

}  // namespace slamvdb::recording
