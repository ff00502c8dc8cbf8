#include "slamvdb/recording/chunk_decompress.hpp"

#include <bzlib.h>
#include <fmt/format.h>
#include <lz4frame.h>

#include <algorithm>
#include <memory>

namespace slamvdb::recording {

Decompressed decompress_lz4_frame(std::span<const std::uint8_t> input, std::size_t max_size,
                                  std::vector<std::uint8_t>& output) {
  // LZ4 expands a byte into at most 255 (a match length extension): a larger claimed size is
  // damage, and is not allocated. The output is allocated once: with linked blocks the decoder
  // refers back into it, so it must not move.
  const std::size_t bound = input.size() * 256 + 65536;
  output.resize(std::min(max_size, bound));
  Decompressed result;
  LZ4F_dctx* raw = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&raw, LZ4F_VERSION))) {
    result.problem = "cannot create an lz4 decompression context";
    output.clear();
    return result;
  }
  const std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> context(raw, &LZ4F_freeDecompressionContext);
  std::size_t consumed = 0;
  std::size_t hint = 1;
  while (consumed < input.size()) {
    std::size_t out_size = output.size() - result.size, in_size = input.size() - consumed;
    hint = LZ4F_decompress(context.get(), output.data() + result.size, &out_size, input.data() + consumed, &in_size,
                           nullptr);
    if (LZ4F_isError(hint)) {
      result.problem = fmt::format("lz4 data damaged after {} of {} bytes: {}", consumed, input.size(),
                                   LZ4F_getErrorName(hint));
      break;
    }
    consumed += in_size;
    result.size += out_size;
    if (hint == 0) break;  // the frame ended (its checksum was checked)
    if (in_size == 0 && out_size == 0) {
      result.problem = fmt::format("lz4 data decompress to more than the {} bytes recorded", max_size);
      break;
    }
  }
  output.resize(result.size);
  if (result.problem.empty()) {
    if (hint != 0)
      result.problem = fmt::format("the lz4 data end after {} bytes, inside a frame (truncated)", input.size());
    else if (consumed != input.size())
      result.problem = fmt::format("{} bytes follow the end of the lz4 frame", input.size() - consumed);
    else if (result.size != max_size)
      result.problem = fmt::format("lz4 data decompress to {} bytes, not the {} recorded", result.size, max_size);
    else
      result.complete = true;
  }
  return result;
}

Decompressed decompress_bz2(std::span<const std::uint8_t> input, std::size_t max_size,
                            std::vector<std::uint8_t>& output) {
  Decompressed result;
  bz_stream stream{};
  if (BZ2_bzDecompressInit(&stream, 0, 0) != BZ_OK) {
    result.problem = "cannot create a bzip2 decompression context";
    output.clear();
    return result;
  }
  // bzip2 can expand a few bytes into megabytes: the output grows with the data, never to a
  // claimed size up front. One byte more than max_size is room to see that there is more.
  const std::size_t cap = max_size + 1;
  output.resize(std::min(cap, std::max<std::size_t>(input.size() * 4, 1 << 16)));
  std::size_t fed = 0;
  int status = BZ_OK;
  while (true) {
    if (stream.avail_in == 0 && fed < input.size()) {  // fed in pieces: avail_in is 32 bits
      const std::size_t more = std::min<std::size_t>(input.size() - fed, 1u << 30);
      stream.next_in = const_cast<char*>(reinterpret_cast<const char*>(input.data() + fed));
      stream.avail_in = static_cast<unsigned>(more);
      fed += more;
    }
    if (result.size == output.size()) {
      if (output.size() >= cap) break;
      output.resize(std::min(cap, output.size() * 2));
    }
    stream.next_out = reinterpret_cast<char*>(output.data() + result.size);
    stream.avail_out = static_cast<unsigned>(std::min<std::size_t>(output.size() - result.size, 1u << 30));
    const unsigned out_before = stream.avail_out, in_before = stream.avail_in;
    status = BZ2_bzDecompress(&stream);
    result.size += out_before - stream.avail_out;
    if (status != BZ_OK) break;
    if (stream.avail_out == out_before && stream.avail_in == in_before) break;  // no progress: input ended
  }
  const std::size_t left_over = stream.avail_in + (input.size() - fed);
  BZ2_bzDecompressEnd(&stream);
  output.resize(result.size);
  if (status == BZ_STREAM_END) {
    if (left_over > 0)
      result.problem = fmt::format("{} bytes follow the end of the bzip2 stream", left_over);
    else if (result.size > max_size)
      result.problem = fmt::format("bzip2 data decompress to more than the {} bytes recorded", max_size);
    else if (result.size != max_size)
      result.problem = fmt::format("bzip2 data decompress to {} bytes, not the {} recorded", result.size, max_size);
    else
      result.complete = true;
  } else if (status == BZ_OK && result.size > max_size) {
    result.problem = fmt::format("bzip2 data decompress to more than the {} bytes recorded", max_size);
  } else if (status == BZ_OK) {
    result.problem = fmt::format("the bzip2 data end after {} bytes, inside the stream (truncated)", input.size());
  } else {
    result.problem = fmt::format("bzip2 data damaged (libbz2 error {}{})", status,
                                 status == BZ_DATA_ERROR_MAGIC ? ": not bzip2 data"
                                 : status == BZ_DATA_ERROR     ? ": a block's CRC does not match"
                                                               : "");
  }
  return result;
}

}  // namespace slamvdb::recording
