#include "slamvdb/io/image_io.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <unistd.h>

#include <array>
#include <cstring>
#include <map>
#include <opencv2/imgcodecs.hpp>  // the cv::ImreadModes flags
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb {

namespace {
// Raw sensor orientation: an EXIF rotation would break the camera calibration.
constexpr int kNoExifRotation = cv::IMREAD_IGNORE_ORIENTATION;

using ReadAt = std::function<bool(std::uint64_t offset, void* destination, std::size_t bytes)>;

uint32_t big_endian(const unsigned char* p, int bytes) {
  uint32_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

// The image header parsers are written by hand: OpenCV 4.6 has no way to ask for an image's size
// without decoding it (cv::imread decodes everything; IMREAD_REDUCED_* still allocates 1/8 of the
// bomb), and libpng / libjpeg are not linked directly. Both formats keep the size in a few bytes
// near the start.

// PNG: 8-byte signature, then the IHDR chunk (length 13) with width and height, 1..2^31-1 each.
std::optional<cv::Size> png_size(const ReadAt& read_at) {
  std::array<unsigned char, 24> h{};
  if (!read_at(0, h.data(), h.size())) return std::nullopt;
  static constexpr std::array<unsigned char, 8> kSignature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!std::equal(kSignature.begin(), kSignature.end(), h.begin())) return std::nullopt;
  if (big_endian(&h[8], 4) != 13 || std::memcmp(&h[12], "IHDR", 4) != 0) return std::nullopt;
  const uint32_t width = big_endian(&h[16], 4), height = big_endian(&h[20], 4);
  if (width == 0 || height == 0 || width > 0x7fffffffu || height > 0x7fffffffu) return std::nullopt;
  return cv::Size(static_cast<int>(width), static_cast<int>(height));
}

// JPEG: walks the marker segments from SOI to the first start-of-frame, which holds the size (as
// libjpeg does: the size it decodes is the first frame's).
std::optional<cv::Size> jpeg_size(const ReadAt& read_at) {
  unsigned char b[5];
  if (!read_at(0, b, 2) || b[0] != 0xff || b[1] != 0xd8) return std::nullopt;
  std::uint64_t pos = 2;
  for (int segment = 0; segment < 4096; ++segment) {  // bounded: no walk over a huge file
    if (!read_at(pos, b, 2) || b[0] != 0xff) return std::nullopt;
    ++pos;
    for (int fill = 0; b[1] == 0xff; ++fill) {  // fill bytes before the marker
      if (fill > 64 || !read_at(++pos, &b[1], 1)) return std::nullopt;
    }
    const unsigned marker = b[1];
    ++pos;
    if (marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) continue;  // standalone, no payload
    if (marker == 0x00 || marker == 0xd8 || marker == 0xd9 || marker == 0xda) return std::nullopt;  // no frame
    if (!read_at(pos, b, 2)) return std::nullopt;
    const uint32_t length = big_endian(b, 2);
    if (length < 2) return std::nullopt;
    const bool start_of_frame = marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
    if (start_of_frame) {
      if (length < 8 || !read_at(pos + 2, b, 5)) return std::nullopt;  // precision, height, width
      const uint32_t height = big_endian(&b[1], 2), width = big_endian(&b[3], 2);
      if (width == 0 || height == 0) return std::nullopt;  // height 0 (defined later by DNL) is not supported
      return cv::Size(static_cast<int>(width), static_cast<int>(height));
    }
    pos += length;
  }
  return std::nullopt;
}

std::int64_t pixels(cv::Size s) { return static_cast<std::int64_t>(s.width) * s.height; }

std::string megapixels(cv::Size s) { return fmt::format("{:.1f} megapixels", static_cast<double>(pixels(s)) / 1e6); }

// Checks the header size of encoded `bytes` (named `name`) against `expected` (or `max_pixels`
// without one) and decodes.
cv::Mat decode_checked_image(std::string_view bytes, const std::string& name, int flags, const char* what,
                             cv::Size expected, std::int64_t max_pixels) {
  const std::string kind = fmt::format("{} image", what);
  const auto size = parse_image_header(bytes);
  if (!size) throw Error(fmt::format("{} {} is neither a PNG nor a JPEG file, or its header is damaged", kind, name));
  if (expected.area() > 0 && *size != expected)
    throw Error(fmt::format("{} {} is {} x {} pixels but the sequence's images are {} x {} (the camera calibration "
                            "refers to that size); it is not resized",
                            kind, name, size->width, size->height, expected.width, expected.height));
  if (expected.area() <= 0 && pixels(*size) > max_pixels)
    throw Error(fmt::format("{} {} is {} x {} = {}, more than the limit of {} (refused before decoding)", kind, name,
                            size->width, size->height, megapixels(*size), static_cast<double>(max_pixels) / 1e6));
  cv::Mat image;
  try {
    image = decode_image(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data())),
                         flags | kNoExifRotation);
  } catch (const cv::Exception& e) {
    throw Error(fmt::format("cannot decode {} {}: {}", kind, name, e.what()));
  }
  if (image.empty()) throw Error(fmt::format("cannot decode {} {}: the file is damaged", kind, name));
  if (image.size() != *size)
    throw Error(fmt::format("{} {} decoded to {} x {} pixels but its header says {} x {}: the file is damaged", kind,
                            name, image.cols, image.rows, size->width, size->height));
  return image;
}

// An image in memory: encoded bytes decoded as a file's, raw pixels checked against `expected`
// and copied (the record keeps its bytes). Colour comes out in `flags`' order (BGR for IMREAD_COLOR).
cv::Mat memory_image(const ImageBytes& image, int flags, const char* what, cv::Size expected, std::int64_t max_pixels) {
  if (image.channels == 0)
    return decode_checked_image(std::string_view(reinterpret_cast<const char*>(image.data.data()), image.data.size()),
                                image.name, flags, what, expected, max_pixels);
  const cv::Size size(image.width, image.height);
  if (expected.area() > 0 && size != expected)
    throw Error(fmt::format("{} image {} is {} x {} pixels but the camera's images are {} x {} (the camera calibration "
                            "refers to that size); it is not resized",
                            what, image.name, size.width, size.height, expected.width, expected.height));
  if (image.channels != 1 && image.channels != 3)
    throw Error(fmt::format("{} image {} has {} channels: expected 1 or 3", what, image.name, image.channels));
  if (image.data.size() != static_cast<std::size_t>(pixels(size)) * static_cast<std::size_t>(image.channels))
    throw Error(fmt::format("{} image {} holds {} bytes, not {} x {} x {}", what, image.name, image.data.size(),
                            size.width, size.height, image.channels));
  const cv::Mat view(size, image.channels == 1 ? CV_8UC1 : CV_8UC3, const_cast<std::uint8_t*>(image.data.data()));
  cv::Mat out;
  if (image.channels == 3 && (flags & cv::IMREAD_COLOR) == cv::IMREAD_COLOR) {
    cv::cvtColor(view, out, cv::COLOR_RGB2BGR);  // as imdecode gives colour
  } else {
    out = view.clone();
  }
  return out;
}

}  // namespace

// Reads, checks the header size against `expected` (or `max_pixels` without one) and decodes.
cv::Mat read_checked_image(const std::filesystem::path& path, int flags, const char* what, cv::Size expected,
                           std::int64_t max_pixels) {
  const std::string bytes = read_regular_file(path, fmt::format("{} image", what), kMaxImageFileBytes);
  return decode_checked_image(bytes, fmt::format("{}", path), flags, what, expected, max_pixels);
}

std::optional<cv::Size> parse_image_header(const ReadAt& read_at) {
  if (auto size = png_size(read_at)) return size;
  return jpeg_size(read_at);
}

std::optional<cv::Size> parse_image_header(std::string_view bytes) {
  return parse_image_header([&](std::uint64_t offset, void* destination, std::size_t n) {
    if (offset > bytes.size() || n > bytes.size() - offset) return false;
    std::memcpy(destination, bytes.data() + offset, n);
    return true;
  });
}

cv::Size read_image_size(const std::filesystem::path& path) {
  const RegularFile file(path, "image");
  const auto size = parse_image_header([&](std::uint64_t offset, void* destination, std::size_t n) {
    if (offset > file.size() || n > file.size() - offset) return false;
    return ::pread(file.fd(), destination, n, static_cast<off_t>(offset)) == static_cast<ssize_t>(n);
  });
  if (!size) throw Error(fmt::format("image {} is neither a PNG nor a JPEG file, or its header is damaged", path));
  return *size;
}

ImageFrame load_image_frame(const ImageRecord& record, bool want_rgb, bool want_labels, std::int64_t max_pixels) {
  ImageFrame frame;
  frame.stamp = record.stamp;
  const cv::Size expected(record.width, record.height);
  if (want_rgb && record.rgb_data) {
    cv::cvtColor(memory_image(*record.rgb_data, cv::IMREAD_COLOR, "camera", expected, max_pixels), frame.rgb,
                 cv::COLOR_BGR2RGB);
    frame.source = record.rgb_data->name;
  } else if (want_rgb && !record.rgb.empty()) {
    cv::cvtColor(read_checked_image(record.rgb, cv::IMREAD_COLOR, "camera", expected, max_pixels), frame.rgb,
                 cv::COLOR_BGR2RGB);
    frame.source = record.rgb.filename().string();
  }
  if (want_labels && record.label_data) {
    frame.labels = memory_image(*record.label_data, cv::IMREAD_UNCHANGED, "label", expected, max_pixels);
    if (frame.labels.type() != CV_8UC1)
      throw Error(fmt::format("label image {} must be 8-bit single-channel class ids, found {} channel(s) of {} bits",
                              record.label_data->name, frame.labels.channels(), 8 * frame.labels.elemSize1()));
    if (frame.source.empty()) frame.source = record.label_data->name;
  }
  if (want_labels && !record.label_data && !record.labels.empty()) {
    frame.labels = read_checked_image(record.labels, cv::IMREAD_UNCHANGED, "label", expected, max_pixels);
    if (frame.labels.type() != CV_8UC1)
      throw Error(fmt::format("label image {} must be 8-bit single-channel class ids, found {} channel(s) of {} bits",
                              record.labels, frame.labels.channels(), 8 * frame.labels.elemSize1()));
    if (frame.source.empty()) frame.source = record.labels.filename().string();
    // The simulated encoder reads labels, and a SIMULATED sequence's view geometry beside them.
    if (!record.view.empty()) {
      // At any size (synth writes it at half the image size); the encoder resamples it like the labels.
      frame.view = read_checked_image(record.view, cv::IMREAD_UNCHANGED, "view geometry", cv::Size(), max_pixels);
      if (frame.view.type() != CV_16UC3)
        throw Error(fmt::format("view geometry image {} must be 16-bit with 3 channels, found {} channel(s) of {} bits",
                                record.view, frame.view.channels(), 8 * frame.view.elemSize1()));
    }
  }
  return frame;
}

cv::Size common_image_size(const std::vector<std::filesystem::path>& images, std::int64_t max_pixels,
                           std::string_view what, std::vector<std::string>& notes) {
  struct Seen {
    std::size_t count = 0, first = 0;
  };
  std::map<std::pair<int, int>, Seen> sizes;
  std::size_t unreadable = 0;
  std::string first_unreadable;
  for (std::size_t i = 0; i < images.size(); ++i) {
    try {
      const cv::Size s = read_image_size(images[i]);
      Seen& seen = sizes[{s.width, s.height}];
      if (seen.count++ == 0) seen.first = i;
    } catch (const Error& e) {
      if (unreadable++ == 0) first_unreadable = e.what();
    }
  }
  if (sizes.empty())
    throw Error(fmt::format("none of the {} {} has a readable PNG or JPEG header (first: {})", images.size(), what,
                            first_unreadable));
  auto best = sizes.begin();
  for (auto it = sizes.begin(); it != sizes.end(); ++it)
    if (it->second.count > best->second.count ||
        (it->second.count == best->second.count && it->second.first < best->second.first))
      best = it;
  const cv::Size size(best->first.first, best->first.second);
  if (pixels(size) > max_pixels)
    throw Error(fmt::format("{} are {} x {} = {}, more than the limit of {} megapixels (--max-image-pixels)", what,
                            size.width, size.height, megapixels(size), static_cast<double>(max_pixels) / 1e6));
  const std::size_t other = images.size() - unreadable - best->second.count;
  if (other > 0) {
    std::string example;
    for (const auto& [s, seen] : sizes)
      if (s != best->first) {
        example = fmt::format("{} is {} x {}", images[seen.first], s.first, s.second);
        break;
      }
    notes.push_back(fmt::format("{} of {} {} have another size than the camera's {} x {} (e.g. {}): they will be "
                                "skipped",
                                other, images.size(), what, size.width, size.height, example));
  }
  if (unreadable > 0)
    notes.push_back(fmt::format("{} of {} {} have no readable PNG or JPEG header (first: {}): they will be skipped",
                                unreadable, images.size(), what, first_unreadable));
  return size;
}

}  // namespace slamvdb
