#pragma once
// Decompression of recording chunks into a caller's buffer, with memory bounded by the real data
// (never by a size a damaged file claims) and a result that says whether the stream was whole, so
// that a reader can recover what precedes the damage of a truncated chunk.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace slamvdb::recording {

struct Decompressed {
  std::size_t size = 0;  // bytes produced (output is resized to this)
  bool complete = false;  // the stream ended properly, its checksums matched, and no input was left over
  std::string problem;    // why not, when !complete
};

// An LZ4 frame (lz4frame.h), as roslz4 and MCAP write chunks. roslz4 writes a standard frame
// (independent blocks, no block checksums, a content checksum, header checksum as the LZ4 frame
// format defines it), so liblz4's frame decoder reads it, checking the content checksum. The output
// stops at `max_size` (the size the container records; more is a problem).
Decompressed decompress_lz4_frame(std::span<const std::uint8_t> input, std::size_t max_size,
                                  std::vector<std::uint8_t>& output);

// A bzip2 stream (libbz2). The output grows as data comes (a claimed size is never allocated up
// front) and stops at `max_size`.
Decompressed decompress_bz2(std::span<const std::uint8_t> input, std::size_t max_size,
                            std::vector<std::uint8_t>& output);

}  // namespace slamvdb::recording
