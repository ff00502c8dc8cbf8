#include "slamvdb/recording/image.hpp"

#include <fmt/format.h>

#include <cstring>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/wire.hpp"

namespace slamvdb::recording {

namespace image_detail {

constexpr std::string_view kImageType = "sensor_msgs/Image";
constexpr std::string_view kSupported = "rgb8, bgr8, rgba8, bgra8, mono8 (8UC1), mono16 (16UC1)";

bool is_mono16(std::string_view encoding) { return encoding == "mono16" || encoding == "16UC1"; }
bool is_mono8(std::string_view encoding) { return encoding == "mono8" || encoding == "8UC1"; }

// What is wrong with the geometry of an image of a supported encoding, or "" (field in `field`).
std::string image_layout_problem(const ImageView& image, std::string_view& field) {
  const std::size_t bpp = image_bytes_per_pixel(image.encoding);
  if (bpp == 0) return {};
  const std::uint64_t row_bytes = std::uint64_t{image.width} * bpp;
  if (image.height > 0 && image.step < row_bytes) {
    field = "step";
    return fmt::format("{} is less than width {} x {} bytes per pixel ({}) = {}", image.step, image.width, bpp,
                       image.encoding, row_bytes);
  }
  const std::uint64_t full = std::uint64_t{image.height} * image.step;
  const std::uint64_t needed = image.height == 0 ? 0 : full - image.step + row_bytes;
  if (image.data.size() < needed || image.data.size() > full) {
    field = "data";
    return fmt::format("has {} bytes where height {} x step {} = {} bytes are expected", image.data.size(),
                       image.height, image.step, full);
  }
  return {};
}

void check_convertible(const ImageView& image) {
  if (image_bytes_per_pixel(image.encoding) == 0)
    throw Error(fmt::format("{}: encoding \"{}\" is not supported (slamvdb reads {})", kImageType, image.encoding,
                            kSupported));
  std::string_view field;
  if (const std::string problem = image_layout_problem(image, field); !problem.empty())
    throw Error(fmt::format("{}: field {} {}", kImageType, field, problem));
}

std::uint16_t mono16_at(const std::uint8_t* p, bool big_endian) {
  return big_endian ? static_cast<std::uint16_t>(p[0] << 8 | p[1]) : static_cast<std::uint16_t>(p[1] << 8 | p[0]);
}

}  // namespace image_detail

std::size_t image_bytes_per_pixel(std::string_view encoding) {
  using namespace image_detail;
  if (encoding == "rgb8" || encoding == "bgr8") return 3;
  if (encoding == "rgba8" || encoding == "bgra8") return 4;
  if (is_mono8(encoding)) return 1;
  if (is_mono16(encoding)) return 2;
  return 0;
}

ImageView decode_image(std::span<const std::uint8_t> bytes, Serialization serialization) {
  using namespace image_detail;
  WireReader reader(bytes, serialization, kImageType);
  ImageView image;
  image.header = read_header(reader);
  image.height = reader.u32("height");
  image.width = reader.u32("width");
  image.encoding = reader.string("encoding");
  image.is_bigendian = reader.u8("is_bigendian") != 0;
  const std::size_t step_at = reader.offset();
  image.step = reader.u32("step");
  const std::size_t data_at = reader.offset();
  image.data = reader.byte_sequence("data");
  reader.expect_end();
  std::string_view field;
  if (const std::string problem = image_layout_problem(image, field); !problem.empty())
    reader.fail_at(field == "step" ? step_at : data_at, field, problem);
  return image;
}

void image_to_rgb8(const ImageView& image, std::vector<std::uint8_t>& rgb) {
  using namespace image_detail;
  check_convertible(image);
  const std::size_t w = image.width, bpp = image_bytes_per_pixel(image.encoding);
  rgb.resize(w * image.height * 3);
  if (rgb.empty()) return;
  const std::string_view e = image.encoding;
  const bool swap_rb = e == "bgr8" || e == "bgra8";
  for (std::size_t row = 0; row < image.height; ++row) {
    const std::uint8_t* in = image.data.data() + row * image.step;
    std::uint8_t* out = rgb.data() + row * w * 3;
    if (e == "rgb8") {
      std::memcpy(out, in, w * 3);
    } else if (bpp >= 3) {
      for (std::size_t i = 0; i < w; ++i, in += bpp, out += 3) {
        out[0] = in[swap_rb ? 2 : 0];
        out[1] = in[1];
        out[2] = in[swap_rb ? 0 : 2];
      }
    } else if (bpp == 1) {
      for (std::size_t i = 0; i < w; ++i, out += 3) out[0] = out[1] = out[2] = in[i];
    } else {
      for (std::size_t i = 0; i < w; ++i, out += 3)
        out[0] = out[1] = out[2] = static_cast<std::uint8_t>(mono16_at(in + 2 * i, image.is_bigendian) >> 8);
    }
  }
}

void image_to_mono8(const ImageView& image, std::vector<std::uint8_t>& mono) {
  using namespace image_detail;
  check_convertible(image);
  if (!is_mono8(image.encoding) && !is_mono16(image.encoding))
    throw Error(fmt::format("{}: encoding \"{}\" is a colour image, not a single-channel label image (mono8 or mono16)",
                            kImageType, image.encoding));
  const std::size_t w = image.width;
  mono.resize(w * image.height);
  if (mono.empty()) return;
  for (std::size_t row = 0; row < image.height; ++row) {
    const std::uint8_t* in = image.data.data() + row * image.step;
    std::uint8_t* out = mono.data() + row * w;
    if (is_mono8(image.encoding)) {
      std::memcpy(out, in, w);
      continue;
    }
    for (std::size_t i = 0; i < w; ++i) {
      const std::uint16_t value = mono16_at(in + 2 * i, image.is_bigendian);
      if (value > 255)
        throw Error(fmt::format("{}: label {} at row {}, column {} does not fit in 8 bits (class ids are below 256)",
                                kImageType, value, row, i));
      out[i] = static_cast<std::uint8_t>(value);
    }
  }
}

}  // namespace slamvdb::recording
