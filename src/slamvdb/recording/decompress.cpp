#include "slamvdb/recording/decompress.hpp"

#include <bzlib.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <fmt/std.h>
#include <unistd.h>
#include <lz4frame.h>
#include <zstd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>
#include <new>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb::recording {

void ByteBuffer::resize(std::size_t size, std::string_view what_for, bool keep) {
  if (size > capacity_) {
    std::unique_ptr<std::uint8_t[]> bigger;
    try {
      bigger.reset(new std::uint8_t[size]);  // not zeroed: the caller overwrites it
    } catch (const std::bad_alloc&) {
      throw Error(fmt::format("cannot allocate {} bytes for {}", size, what_for));
    }
    if (keep && size_ > 0) std::memcpy(bigger.get(), data_.get(), size_);
    data_ = std::move(bigger);
    capacity_ = size;
  }
  size_ = size;
}

bool plausible_uncompressed_size(std::uint64_t compressed, std::uint64_t uncompressed, std::uint64_t max_ratio) {
  constexpr std::uint64_t kSlack = std::uint64_t{1} << 20;
  if (compressed > (UINT64_MAX - kSlack) / max_ratio) return true;
  return uncompressed <= compressed * max_ratio + kSlack;
}

bool is_zstd_frame(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= 4 && bytes[0] == 0x28 && bytes[1] == 0xB5 && bytes[2] == 0x2F && bytes[3] == 0xFD;
}

struct Decompressor::Contexts {
  ZSTD_DCtx* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;
  ~Contexts() {
    if (zstd) ZSTD_freeDCtx(zstd);
    if (lz4) LZ4F_freeDecompressionContext(lz4);
  }
  // After an error an LZ4F context is in an undefined state: start a new one.
  void renew_lz4() {
    if (lz4) LZ4F_freeDecompressionContext(lz4);
    lz4 = nullptr;
    if (LZ4F_isError(LZ4F_createDecompressionContext(&lz4, LZ4F_VERSION))) throw std::bad_alloc();
  }
};

Decompressor::Decompressor() : contexts_(std::make_unique<Contexts>()) {
  contexts_->zstd = ZSTD_createDCtx();
  if (!contexts_->zstd) throw std::bad_alloc();
  contexts_->renew_lz4();
}

Decompressor::~Decompressor() = default;

void Decompressor::zstd_exact(std::span<const std::uint8_t> in, std::span<std::uint8_t> out, std::string_view where) {
  const unsigned long long declared = ZSTD_getFrameContentSize(in.data(), in.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR)
    throw Error(fmt::format("{}: the zstd data does not start with a zstd frame header", where));
  // Several frames are allowed; a single frame that declares its size must declare this one.
  if (declared != ZSTD_CONTENTSIZE_UNKNOWN && declared > out.size())
    throw Error(fmt::format("{}: the zstd frame holds {} bytes, more than the {} bytes declared", where, declared,
                            out.size()));
  const std::size_t n = ZSTD_decompressDCtx(contexts_->zstd, out.data(), out.size(), in.data(), in.size());
  if (ZSTD_isError(n))
    throw Error(fmt::format("{}: the zstd data is damaged ({})", where, ZSTD_getErrorName(n)));
  if (n != out.size())
    throw Error(fmt::format("{}: the zstd data decompresses to {} bytes, not the {} declared", where, n, out.size()));
}

namespace decompress_detail {

// Where one run of the LZ4 frame decoder stopped.
struct Lz4Run {
  std::size_t in_pos = 0, out_pos = 0;
  std::size_t hint = 1;   // LZ4F_decompress's last return: 0 at the end of a frame
  std::size_t error = 0;  // an LZ4F error code (hint is then the size before it), 0 if none
  bool output_full = false;  // no progress: the output is full with input left
};

// The one LZ4 frame decoding loop: feeds `in` to `context`, writing `out` front to back, until the
// input is used up, an error, the output is full, or (`one_frame`) the end of the first frame.
// After an error or a stop inside a frame the context is in an undefined state: the caller renews it.
Lz4Run run_lz4_frames(LZ4F_dctx* context, std::span<const std::uint8_t> in, std::span<std::uint8_t> out,
                      bool checksums, bool one_frame) {
  Lz4Run run;
  LZ4F_decompressOptions_t options{};
  options.stableDst = 1;  // one output buffer, written front to back: no copies through LZ4F's own
  options.skipChecksums = checksums ? 0 : 1;
  while (run.in_pos < in.size()) {
    std::size_t out_size = out.size() - run.out_pos, in_size = in.size() - run.in_pos;
    const std::size_t hint =
        LZ4F_decompress(context, out.data() + run.out_pos, &out_size, in.data() + run.in_pos, &in_size, &options);
    if (LZ4F_isError(hint)) {
      run.error = hint;
      break;
    }
    run.hint = hint;
    run.in_pos += in_size;
    run.out_pos += out_size;
    if (hint == 0 && one_frame) break;  // the frame ended (its checksum was checked)
    if (in_size == 0 && out_size == 0) {
      run.output_full = true;
      break;
    }
  }
  return run;
}

}  // namespace decompress_detail

void Decompressor::lz4_frame_exact(std::span<const std::uint8_t> in, std::span<std::uint8_t> out,
                                   std::string_view where, bool checksums) {
  const decompress_detail::Lz4Run run = decompress_detail::run_lz4_frames(contexts_->lz4, in, out, checksums, false);
  if (run.error != 0) {
    contexts_->renew_lz4();
    throw Error(fmt::format("{}: the LZ4 data is damaged ({})", where, LZ4F_getErrorName(run.error)));
  }
  if (run.hint != 0 || run.in_pos != in.size()) {
    contexts_->renew_lz4();
    if (run.out_pos == out.size() && run.in_pos != in.size())
      throw Error(fmt::format("{}: the LZ4 data decompresses to more than the {} bytes declared", where, out.size()));
    throw Error(fmt::format("{}: the LZ4 data ends inside a frame (truncated)", where));
  }
  if (run.out_pos != out.size())
    throw Error(
        fmt::format("{}: the LZ4 data decompresses to {} bytes, not the {} declared", where, run.out_pos, out.size()));
}

Decompressed Decompressor::lz4_frame_recover(std::span<const std::uint8_t> in, std::size_t max_size,
                                             std::vector<std::uint8_t>& output) {
  // LZ4 expands a byte into at most 255 (a match length extension): a larger claimed size is
  // damage, and is not allocated. The output is allocated once: with linked blocks the decoder
  // refers back into it, so it must not move.
  output.resize(std::min<std::uint64_t>(max_size, std::uint64_t{in.size()} * kMaxLz4Ratio + 65536));
  const decompress_detail::Lz4Run run = decompress_detail::run_lz4_frames(contexts_->lz4, in, output, true, true);
  Decompressed result;
  result.size = run.out_pos;
  output.resize(result.size);
  if (run.error != 0)
    result.problem = fmt::format("lz4 data damaged after {} of {} bytes: {}", run.in_pos, in.size(),
                                 LZ4F_getErrorName(run.error));
  else if (run.output_full)
    result.problem = fmt::format("lz4 data decompress to more than the {} bytes recorded", max_size);
  else if (run.hint != 0)
    result.problem = fmt::format("the lz4 data end after {} bytes, inside a frame (truncated)", in.size());
  else if (run.in_pos != in.size())
    result.problem = fmt::format("{} bytes follow the end of the lz4 frame", in.size() - run.in_pos);
  else if (result.size != max_size)
    result.problem = fmt::format("lz4 data decompress to {} bytes, not the {} recorded", result.size, max_size);
  else
    result.complete = true;
  if (run.error != 0 || run.hint != 0) contexts_->renew_lz4();
  return result;
}

void Decompressor::zstd_any(std::span<const std::uint8_t> in, ByteBuffer& out, std::uint64_t max_out,
                            std::string_view where) {
  const unsigned long long declared = ZSTD_getFrameContentSize(in.data(), in.size());
  if (declared == ZSTD_CONTENTSIZE_ERROR)
    throw Error(fmt::format("{}: the data is not a zstd frame", where));
  std::uint64_t capacity = declared != ZSTD_CONTENTSIZE_UNKNOWN ? declared : std::max<std::uint64_t>(in.size() * 4, 4096);
  if (capacity > max_out)
    throw Error(fmt::format("{}: the zstd frame declares {} bytes, more than the {} it can hold", where, capacity, max_out));
  out.resize(static_cast<std::size_t>(capacity), where);
  ZSTD_DCtx_reset(contexts_->zstd, ZSTD_reset_session_only);
  ZSTD_inBuffer input{in.data(), in.size(), 0};
  ZSTD_outBuffer output{out.data(), out.size(), 0};
  while (true) {
    const std::size_t r = ZSTD_decompressStream(contexts_->zstd, &output, &input);
    if (ZSTD_isError(r)) {
      ZSTD_DCtx_reset(contexts_->zstd, ZSTD_reset_session_only);
      throw Error(fmt::format("{}: the zstd data is damaged ({})", where, ZSTD_getErrorName(r)));
    }
    if (input.pos == input.size && r == 0) break;  // every frame complete
    if (output.pos < output.size) {
      if (input.pos == input.size) {
        ZSTD_DCtx_reset(contexts_->zstd, ZSTD_reset_session_only);
        throw Error(fmt::format("{}: the zstd data ends inside a frame (truncated)", where));
      }
      continue;
    }
    // Output full: grow (up to max_out).
    if (out.size() >= max_out) {
      ZSTD_DCtx_reset(contexts_->zstd, ZSTD_reset_session_only);
      throw Error(fmt::format("{}: the zstd data decompresses to more than {} bytes", where, max_out));
    }
    const std::uint64_t grown = std::min<std::uint64_t>(max_out, std::uint64_t{out.size()} * 2);
    out.resize(static_cast<std::size_t>(grown), where, true);
    output.dst = out.data();
    output.size = out.size();
  }
  out.resize(output.pos, where, true);
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

std::uint64_t decompress_zstd_file(const std::filesystem::path& in, const std::filesystem::path& out,
                                   std::string_view what) {
  RegularFile source(in, what);
  const int fd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) throw Error(fmt::format("cannot create {}: {}", out, std::strerror(errno)));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  auto write_all = [&](const char* p, std::size_t n) {
    while (n > 0) {
      const ssize_t w = ::write(fd, p, n);
      if (w < 0 && errno == EINTR) continue;
      if (w < 0)
        throw Error(fmt::format("cannot write the decompressed copy of {} {} to {}: {}", what, in, out,
                                std::strerror(errno)));
      p += w;
      n -= static_cast<std::size_t>(w);
    }
  };
  ZSTD_DStream* stream = ZSTD_createDStream();
  if (!stream) throw std::bad_alloc();
  struct Freer {
    ZSTD_DStream* s;
    ~Freer() { ZSTD_freeDStream(s); }
  } freer{stream};
  std::vector<char> input(ZSTD_DStreamInSize()), output(ZSTD_DStreamOutSize());
  std::uint64_t left = source.size(), written = 0;
  std::size_t last = 0;
  if (left == 0) throw Error(fmt::format("{} {} is empty, not zstd data", what, in));
  while (left > 0) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, input.size()));
    source.read_exact(input.data(), n);
    left -= n;
    ZSTD_inBuffer in_buffer{input.data(), n, 0};
    while (in_buffer.pos < in_buffer.size) {
      ZSTD_outBuffer out_buffer{output.data(), output.size(), 0};
      last = ZSTD_decompressStream(stream, &out_buffer, &in_buffer);
      if (ZSTD_isError(last))
        throw Error(fmt::format("{} {} is damaged near byte {} ({})", what, in, source.size() - left - n + in_buffer.pos,
                                ZSTD_getErrorName(last)));
      write_all(output.data(), out_buffer.pos);
      written += out_buffer.pos;
    }
  }
  // Flush what the decoder still holds.
  while (last != 0) {
    ZSTD_inBuffer none{nullptr, 0, 0};
    ZSTD_outBuffer out_buffer{output.data(), output.size(), 0};
    last = ZSTD_decompressStream(stream, &out_buffer, &none);
    if (ZSTD_isError(last)) throw Error(fmt::format("{} {} is damaged ({})", what, in, ZSTD_getErrorName(last)));
    if (out_buffer.pos == 0) break;
    write_all(output.data(), out_buffer.pos);
    written += out_buffer.pos;
  }
  if (last != 0) throw Error(fmt::format("{} {} ends inside a zstd frame (truncated)", what, in));
  return written;
}

}  // namespace slamvdb::recording
