#include "slamvdb/eval/label_images.hpp"

#include <fmt/format.h>

#include <opencv2/imgcodecs.hpp>  // the cv::ImreadModes flags
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/image_io.hpp"

namespace slamvdb {

std::vector<uint16_t> read_labels_at(const std::filesystem::path& path, int width, int height) {
  // The file's size and its header's image size are checked before decoding (a damaged or huge
  // label file is an Error naming it, not an allocation of gigabytes).
  const cv::Mat labels = read_checked_image(path, cv::IMREAD_UNCHANGED, "label");
  if (labels.channels() != 1 || (labels.depth() != CV_8U && labels.depth() != CV_16U))
    throw Error(fmt::format("label image {} is not single-channel 8- or 16-bit class ids", path.string()));
  cv::Mat resized;
  cv::resize(labels, resized, cv::Size(width, height), 0, 0, cv::INTER_NEAREST);
  cv::Mat ids;
  resized.convertTo(ids, CV_16U);
  std::vector<uint16_t> out(static_cast<std::size_t>(width) * height);
  for (int y = 0; y < height; ++y) {
    const uint16_t* row = ids.ptr<uint16_t>(y);
    std::copy(row, row + width, out.begin() + static_cast<std::ptrdiff_t>(y) * width);
  }
  return out;
}

}  // namespace slamvdb
