#include "slamvdb/io/image_codecs.hpp"

#include "slamvdb/core/plugin_library.hpp"

namespace slamvdb {
namespace {

const ImageCodecFunctions& codecs() {
  static const ImageCodecFunctions& functions = plugin_exports<ImageCodecFunctions>(
      SLAMVDB_IMAGE_CODECS_PLUGIN, kImageCodecsSymbol, "image encoding and decoding (OpenCV imgcodecs)",
      kImageCodecsVersion);
  return functions;
}

}  // namespace

cv::Mat decode_image(const cv::Mat& encoded, int flags) { return codecs().decode(encoded, flags); }

bool encode_image(const std::string& extension, const cv::Mat& image, std::vector<unsigned char>& encoded,
                  const std::vector<int>& params) {
  return codecs().encode(extension, image, encoded, params);
}

}  // namespace slamvdb
