#pragma once
// Camera images and 2D label images: PNG and JPEG only, sized from their headers before any
// pixel is decoded, so that a small file claiming a huge image (a decompression bomb: 0.9 MB of
// PNG can decode to 30000 x 30000) is refused instead of allocating gigabytes.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/inference/encoders.hpp"
#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

// Largest image file read (the encoded bytes): 256 MiB.
inline constexpr std::uint64_t kMaxImageFileBytes = std::uint64_t{256} << 20;

// Width and height from the header of a PNG (IHDR) or a JPEG (first start-of-frame marker), read
// through `read_at(offset, destination, bytes)`, which returns false past the end of the data.
// nullopt if the data is neither, or its header is damaged (e.g. a zero or negative size).
std::optional<cv::Size> parse_image_header(
    const std::function<bool(std::uint64_t offset, void* destination, std::size_t bytes)>& read_at);
// The same on bytes in memory.
std::optional<cv::Size> parse_image_header(std::string_view bytes);

// Width and height of an image file from its PNG or JPEG header, without decoding the pixels.
// Throws Error naming the file if it is not a regular file or neither a PNG nor a JPEG.
cv::Size read_image_size(const std::filesystem::path& path);

// Reads an image file (at most kMaxImageFileBytes), checks its header size against `expected`, or
// against `max_pixels` when `expected` is empty, and decodes it with cv::imdecode `flags`. Throws
// Error naming the file (`what`: e.g. "label") if it cannot be read, is neither a PNG nor a JPEG,
// is too large, or is damaged. Sizes are checked before decoding.
cv::Mat read_checked_image(const std::filesystem::path& path, int flags, const char* what, cv::Size expected = {},
                           std::int64_t max_pixels = kDefaultMaxImagePixels);

// Loads the requested parts of an image record: rgb as CV_8UC3 in RGB order, labels as CV_8UC1
// (with them a SIMULATED sequence's view geometry, CV_16UC3, when the record has one).
// A part whose path is empty stays empty. Throws Error naming the file if it cannot be read or
// decoded, if its header size differs from the record's expected size (ImageRecord::width and
// height, set by the sequence readers to the camera's size), or, for a record without an expected
// size, if it has more than `max_pixels` pixels. Sizes are checked before decoding.
ImageFrame load_image_frame(const ImageRecord& record, bool want_rgb, bool want_labels,
                            std::int64_t max_pixels = kDefaultMaxImagePixels);

// The size most of `images` have according to their headers (the camera's size; ties go to the
// earliest image). A damaged first image thus cannot change the camera model. Appends a note
// counting the images whose header gives another size or none (they fail when loaded). Throws
// Error if no image has a readable header, or if the size is above `max_pixels` (`what` names the
// images, e.g. "camera images in DIR").
cv::Size common_image_size(const std::vector<std::filesystem::path>& images, std::int64_t max_pixels,
                           std::string_view what, std::vector<std::string>& notes);

}  // namespace slamvdb
