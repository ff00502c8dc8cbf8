#pragma once
// Encoding and decoding images (PNG, JPEG and OpenCV's other formats) with OpenCV's imgcodecs,
// which lives in a plugin library loaded by the first call (core/plugin_library.hpp). Why:
// Debian's libopencv_imgcodecs links about 140 shared libraries (GDAL, GDCM, HEIF, ...), and
// loading them cost every CLI start 0.17 CPU-s in Release and about 0.4 CPU-s under ASan, also in
// the runs that never touch an image (`info`, `query`, `merge`, `--help`, ...).
// Nothing else in the project calls cv::imread / imdecode / imencode / imwrite: the parts do not
// link imgcodecs, so such a call is a link error (the tests may, to make their fixtures).
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace slamvdb {

// cv::imdecode of `encoded` (bytes, e.g. a 1 x N CV_8UC1 matrix) with cv::ImreadModes `flags`:
// empty if the bytes are no image imgcodecs can decode. cv::Exception passes through.
cv::Mat decode_image(const cv::Mat& encoded, int flags);

// cv::imencode: `extension` such as ".png" or ".jpg", `params` cv::ImwriteFlags pairs. False if it
// cannot encode `image` so. cv::Exception passes through.
bool encode_image(const std::string& extension, const cv::Mat& image, std::vector<unsigned char>& encoded,
                  const std::vector<int>& params = {});

// What the plugin library (image_codecs_plugin.cpp) exports by kImageCodecsSymbol; the version is
// checked when it is loaded.
struct ImageCodecFunctions {
  int version = 0;
  cv::Mat (*decode)(const cv::Mat& encoded, int flags) = nullptr;
  bool (*encode)(const std::string& extension, const cv::Mat& image, std::vector<unsigned char>& encoded,
                 const std::vector<int>& params) = nullptr;
};
inline constexpr int kImageCodecsVersion = 1;
inline constexpr const char* kImageCodecsSymbol = "slamvdb_image_codecs";

}  // namespace slamvdb
