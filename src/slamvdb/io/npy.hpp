#pragma once
// NumPy .npy files for precomputed dense feature maps (C x H x W on disk, pixel-major in memory).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "slamvdb/core/feature_map.hpp"

namespace slamvdb {

// Largest .npy feature file read: 1 GiB (a 512 x 128 x 192 float32 map is 50 MB).
inline constexpr std::uint64_t kMaxNpyFileBytes = std::uint64_t{1} << 30;

// Reads a little-endian, C-ordered float32 or float16 array of shape C x H x W or 1 x C x H x W
// and transposes it to the pixel-major FeatureMap in the file's precision (a float16 file gives an
// fp16 map, not widened: fusion reads half the bytes). Anything else (including a path that is not
// a regular file, or a file above kMaxNpyFileBytes) throws Error naming the file.
FeatureMap read_feature_npy(const std::filesystem::path& path);
// The same into `map`, reusing its storage: a caller reading one map per frame avoids faulting in
// a fresh 50 MB buffer each time (that costs as much as the transpose).
void read_feature_npy(const std::filesystem::path& path, FeatureMap& map);

// Writes the map as a C x H x W float32 array (an fp16 map widened, exactly), through the one
// output writer (core/output_file.hpp): a failure leaves no partial file, and an existing file is
// replaced only by a complete one.
void write_feature_npy(const std::filesystem::path& path, const FeatureMap& map);

// Vectors from a float32 or float16 array of shape (dim,) or (n, dim): one row per vector (query
// vectors for `slamvdb query --vector`). Throws Error naming the file for anything else.
std::vector<std::vector<float>> read_npy_vectors(const std::filesystem::path& path);

// Writes a C-ordered float32 array of the given shape (format version 1.0).
void write_npy_array(const std::filesystem::path& path, const float* data, const std::vector<std::size_t>& shape);
enum class NpyDtype { kFloat32, kInt32 };
void write_npy_array(const std::filesystem::path& path, const void* data, const std::vector<std::size_t>& shape,
                     NpyDtype dtype);

}  // namespace slamvdb
