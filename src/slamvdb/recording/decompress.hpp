#pragma once
// Decompression for the recording containers: zstd frames (MCAP chunks, rosbag2 messages and files),
// LZ4 frames (MCAP and ROS 1 bag chunks) and bzip2 streams (ROS 1 bag chunks), through libzstd,
// liblz4 and libbz2. Sizes declared by a file are checked against what the compressed bytes can
// plausibly hold before anything is allocated, so that a damaged size field is an Error (or a
// problem reported), not an attempt to allocate terabytes.
// Two kinds of result: the *_exact calls want exactly the declared size and throw Error otherwise
// (MCAP, rosbag2); the recovering calls keep what decompresses before damage or a cut and say why
// the stream was not whole (ROS 1 bags, whose truncated chunks are salvaged).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace slamvdb::recording {

// Bytes that are not zeroed when allocated (a chunk buffer is always overwritten whole), reused
// across chunks: it only grows.
class ByteBuffer {
 public:
  std::uint8_t* data() { return data_.get(); }
  const std::uint8_t* data() const { return data_.get(); }
  std::size_t size() const { return size_; }
  std::span<std::uint8_t> span() { return {data_.get(), size_}; }
  std::span<const std::uint8_t> span() const { return {data_.get(), size_}; }
  // Sets the size, keeping the first min(old, new) bytes only if `keep`; throws Error (naming
  // `what_for`) when the memory cannot be had.
  void resize(std::size_t size, std::string_view what_for, bool keep = false);

 private:
  std::unique_ptr<std::uint8_t[]> data_;
  std::size_t size_ = 0, capacity_ = 0;
};

// The largest expansion each format can produce: zstd's smallest block (an RLE block, 4 bytes)
// stands for 128 KiB; an LZ4 match length grows by 255 per byte. A declared uncompressed size
// beyond compressed * ratio + 1 MiB is damage.
inline constexpr std::uint64_t kMaxZstdRatio = 32768;
inline constexpr std::uint64_t kMaxLz4Ratio = 256;
bool plausible_uncompressed_size(std::uint64_t compressed, std::uint64_t uncompressed, std::uint64_t max_ratio);

// What a recovering decompression produced.
struct Decompressed {
  std::size_t size = 0;  // bytes produced (output is resized to this)
  bool complete = false;  // the stream ended properly, its checksums matched, and no input was left over
  std::string problem;    // why not, when !complete
};

class Decompressor {
 public:
  Decompressor();
  ~Decompressor();
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;

  // One or more zstd frames that decompress to exactly out.size() bytes. Throws Error
  // "<where>: <what was wrong>" on damage or a size mismatch.
  void zstd_exact(std::span<const std::uint8_t> in, std::span<std::uint8_t> out, std::string_view where);
  // One or more LZ4 frames (the LZ4 frame format, magic 04 22 4D 18) that decompress to exactly
  // out.size() bytes. The frames' own checksums are checked when they have them and `checksums`
  // is true; a caller that checks a CRC of the output itself passes false (a second pass over the
  // output costs a fifth of the decompression's time).
  void lz4_frame_exact(std::span<const std::uint8_t> in, std::span<std::uint8_t> out, std::string_view where,
                       bool checksums = true);
  // One LZ4 frame (as roslz4 and MCAP write chunks: roslz4 writes a standard frame, independent
  // blocks, a content checksum, which is checked) into `output`, recovering: what decompresses
  // before damage or the end of a cut stream is kept. The output stops at `max_size` (the size the
  // container records; more is a problem) and is never allocated beyond what the input can hold.
  Decompressed lz4_frame_recover(std::span<const std::uint8_t> in, std::size_t max_size,
                                 std::vector<std::uint8_t>& output);
  // zstd frames of any size (declared in the frame header or not) into `out`, at most `max_out` bytes.
  void zstd_any(std::span<const std::uint8_t> in, ByteBuffer& out, std::uint64_t max_out, std::string_view where);

 private:
  struct Contexts;
  std::unique_ptr<Contexts> contexts_;
};

// A bzip2 stream (libbz2) into `output`, recovering as lz4_frame_recover does. The output grows as
// data comes (a claimed size is never allocated up front) and stops at `max_size`.
Decompressed decompress_bz2(std::span<const std::uint8_t> input, std::size_t max_size,
                            std::vector<std::uint8_t>& output);

// Decompresses the zstd file `in` (one or more frames, as `zstd` or rosbag2's FILE compression
// writes it) into the new file `out`, streaming (memory stays small whatever the size). Returns the
// bytes written. Throws Error naming `in` on damage and `out` when it cannot be written (a full disk).
std::uint64_t decompress_zstd_file(const std::filesystem::path& in, const std::filesystem::path& out,
                                   std::string_view what);

// Whether the bytes start with a zstd frame's magic number (28 B5 2F FD).
bool is_zstd_frame(std::span<const std::uint8_t> bytes);

}  // namespace slamvdb::recording
