#pragma once
// 2D label images at the resolution of a feature map.
#include <cstdint>
#include <filesystem>
#include <vector>

namespace slamvdb {

// The label image at `path` (8- or 16-bit single channel ids) resampled to width x height by
// nearest neighbour, row-major. cv::INTER_NEAREST, as the simulated dense encoder resamples the
// same image, so labels and simulated features line up pixel for pixel. Throws Error naming the
// file if it cannot be read or is not a single-channel 8/16-bit image.
std::vector<uint16_t> read_labels_at(const std::filesystem::path& path, int width, int height);

}  // namespace slamvdb
