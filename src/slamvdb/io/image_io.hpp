#pragma once
// Camera images and 2D label images.
#include <filesystem>
#include <opencv2/core.hpp>

#include "slamvdb/inference/encoders.hpp"
#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

// Loads the requested parts of an image record: rgb as CV_8UC3 in RGB order, labels as CV_8UC1.
// A part whose path is empty stays empty; a path that cannot be decoded throws Error.
ImageFrame load_image_frame(const ImageRecord& record, bool want_rgb, bool want_labels);

// Width and height from a PNG or JPEG header without decoding the pixels (other formats are
// decoded). Throws Error if the file cannot be read.
cv::Size read_image_size(const std::filesystem::path& path);

}  // namespace slamvdb
