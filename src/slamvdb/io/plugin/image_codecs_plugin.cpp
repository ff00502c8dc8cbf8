// The plugin library libslamvdb_image_codecs.so (image_codecs.hpp): the only code of the project
// that links OpenCV's imgcodecs.
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/io/image_codecs.hpp"

namespace {

cv::Mat decode(const cv::Mat& encoded, int flags) { return cv::imdecode(encoded, flags); }

bool encode(const std::string& extension, const cv::Mat& image, std::vector<unsigned char>& encoded,
            const std::vector<int>& params) {
  return cv::imencode(extension, image, encoded, params);
}

const slamvdb::ImageCodecFunctions kFunctions{slamvdb::kImageCodecsVersion, &decode, &encode};

}  // namespace

extern "C" __attribute__((visibility("default"))) const slamvdb::ImageCodecFunctions* slamvdb_image_codecs() {
  return &kFunctions;
}
