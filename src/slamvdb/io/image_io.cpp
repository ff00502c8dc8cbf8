#include "slamvdb/io/image_io.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <array>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "slamvdb/core/error.hpp"

namespace slamvdb {

namespace {
// Raw sensor orientation: an EXIF rotation would break the camera calibration.
constexpr int kNoExifRotation = cv::IMREAD_IGNORE_ORIENTATION;

int big_endian(const unsigned char* p, int bytes) {
  int v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

std::optional<cv::Size> png_size(std::istream& in) {
  std::array<unsigned char, 24> h{};
  if (!in.read(reinterpret_cast<char*>(h.data()), h.size())) return std::nullopt;
  static constexpr std::array<unsigned char, 8> kSignature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (!std::equal(kSignature.begin(), kSignature.end(), h.begin())) return std::nullopt;
  return cv::Size(big_endian(&h[16], 4), big_endian(&h[20], 4));
}

// Walks the JPEG marker segments up to the first start-of-frame, which holds the size.
std::optional<cv::Size> jpeg_size(std::istream& in) {
  unsigned char soi[2];
  if (!in.read(reinterpret_cast<char*>(soi), 2) || soi[0] != 0xff || soi[1] != 0xd8) return std::nullopt;
  while (in) {
    int byte = in.get();
    if (byte != 0xff) return std::nullopt;
    int marker;
    do marker = in.get();
    while (marker == 0xff);
    if (marker == EOF) return std::nullopt;
    if (marker == 0xd8 || marker == 0x01 || (marker >= 0xd0 && marker <= 0xd7)) continue;  // no payload
    unsigned char len[2];
    if (!in.read(reinterpret_cast<char*>(len), 2)) return std::nullopt;
    const int length = big_endian(len, 2);
    const bool start_of_frame = marker >= 0xc0 && marker <= 0xcf && marker != 0xc4 && marker != 0xc8 && marker != 0xcc;
    if (start_of_frame) {
      unsigned char sof[5];  // precision, height, width
      if (!in.read(reinterpret_cast<char*>(sof), 5)) return std::nullopt;
      return cv::Size(big_endian(&sof[3], 2), big_endian(&sof[1], 2));
    }
    in.seekg(length - 2, std::ios::cur);
  }
  return std::nullopt;
}

cv::Mat read_or_throw(const std::filesystem::path& path, int flags, const char* what) {
  if (!std::filesystem::is_regular_file(path)) throw Error(fmt::format("{} image {} does not exist", what, path));
  cv::Mat image = cv::imread(path.string(), flags | kNoExifRotation);
  if (image.empty()) throw Error(fmt::format("cannot read {} image {}", what, path));
  return image;
}
}  // namespace

ImageFrame load_image_frame(const ImageRecord& record, bool want_rgb, bool want_labels) {
  ImageFrame frame;
  frame.stamp = record.stamp;
  if (want_rgb && !record.rgb.empty()) {
    cv::cvtColor(read_or_throw(record.rgb, cv::IMREAD_COLOR, "camera"), frame.rgb, cv::COLOR_BGR2RGB);
    frame.source = record.rgb.filename().string();
  }
  if (want_labels && !record.labels.empty()) {
    frame.labels = read_or_throw(record.labels, cv::IMREAD_UNCHANGED, "label");
    if (frame.labels.type() != CV_8UC1)
      throw Error(fmt::format("label image {} must be 8-bit single-channel class ids, found {} channel(s) of {} bits",
                              record.labels, frame.labels.channels(), 8 * frame.labels.elemSize1()));
    if (frame.source.empty()) frame.source = record.labels.filename().string();
  }
  return frame;
}

cv::Size read_image_size(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(fmt::format("cannot open image {}", path));
  if (auto size = png_size(in)) return *size;
  in.clear();
  in.seekg(0);
  if (auto size = jpeg_size(in)) return *size;
  return read_or_throw(path, cv::IMREAD_UNCHANGED, "camera").size();
}

}  // namespace slamvdb
