#pragma once
// CRC-32 (the IEEE / zlib / MCAP one: reflected polynomial 0xEDB88320), fast enough not to slow
// reading: checking a recording's chunk CRCs must cost far less than decompressing them. zlib's
// crc32 runs at ~0.6 GB/s on this project's machines; this folds 64 bytes per step with carry-less
// multiplication (PCLMULQDQ, chosen at run time, ~10x faster) and falls back to zlib otherwise.
#include <cstddef>
#include <cstdint>

namespace slamvdb::recording {

// crc32(crc32(0, a), b) == crc32(0, a + b), like zlib's crc32().
std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size);

}  // namespace slamvdb::recording
