#include "slamvdb/recording/crc32.hpp"

#include <zlib.h>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define SLAMVDB_CRC_CLMUL 1
#endif

namespace slamvdb::recording {

namespace crc32_detail {

#ifdef SLAMVDB_CRC_CLMUL
// Folding with carry-less multiplication (Gopal et al., "Fast CRC computation for generic polynomials
// using PCLMULQDQ", Intel 2009), for the bit-reflected CRC-32. Four 128-bit lanes are folded 64 bytes
// ahead at a time, then into one lane, then reduced to 32 bits (Barrett). The constants are powers
// of x modulo the polynomial, bit-reflected: k1 = x^(4*128+32), k2 = x^(4*128-32), k3 = x^(128+32),
// k4 = x^(128-32), k5 = x^64 (mod P), and P itself with mu = floor(x^64 / P) for the reduction.
#define SLAMVDB_CLMUL __attribute__((target("pclmul,sse4.1")))

SLAMVDB_CLMUL inline __m128i load16(const unsigned char* q) {
  return _mm_loadu_si128(reinterpret_cast<const __m128i*>(q));
}
// a (128 bits) moved forward by the distance its constants k encode and added to b: the low half
// times k's low half plus the high half times k's high half.
SLAMVDB_CLMUL inline __m128i fold16(__m128i a, __m128i b, __m128i k) {
  return _mm_xor_si128(_mm_xor_si128(_mm_clmulepi64_si128(a, k, 0x00), _mm_clmulepi64_si128(a, k, 0x11)), b);
}

// `state` is the running register (the complement of zlib's crc); `size` >= 64, a multiple of 16.
SLAMVDB_CLMUL std::uint32_t fold_clmul(std::uint32_t state, const unsigned char* p,
                                                                  std::size_t size) {
  const __m128i k1k2 = _mm_set_epi64x(0x1c6e41596, 0x154442bd4);
  const __m128i k3k4 = _mm_set_epi64x(0x0ccaa009e, 0x1751997d0);
  const __m128i k5 = _mm_set_epi64x(0, 0x163cd6124);
  const __m128i poly_mu = _mm_set_epi64x(0x1f7011641, 0x1db710641);
  const __m128i low32 = _mm_setr_epi32(-1, 0, -1, 0);

  __m128i x0 = _mm_xor_si128(load16(p), _mm_cvtsi32_si128(static_cast<int>(state)));
  __m128i x1 = load16(p + 16), x2 = load16(p + 32), x3 = load16(p + 48);
  p += 64;
  size -= 64;
  for (; size >= 64; size -= 64, p += 64) {
    x0 = fold16(x0, load16(p), k1k2);
    x1 = fold16(x1, load16(p + 16), k1k2);
    x2 = fold16(x2, load16(p + 32), k1k2);
    x3 = fold16(x3, load16(p + 48), k1k2);
  }
  x0 = fold16(x0, x1, k3k4);
  x0 = fold16(x0, x2, k3k4);
  x0 = fold16(x0, x3, k3k4);
  for (; size >= 16; size -= 16, p += 16) x0 = fold16(x0, load16(p), k3k4);
  // 128 -> 64 bits.
  x0 = _mm_xor_si128(_mm_srli_si128(x0, 8), _mm_clmulepi64_si128(x0, k3k4, 0x10));
  // 64 -> 32 bits.
  x0 = _mm_xor_si128(_mm_srli_si128(x0, 4), _mm_clmulepi64_si128(_mm_and_si128(x0, low32), k5, 0x00));
  // Barrett reduction: q = (low 32 bits * mu), then subtract q * P.
  __m128i q = _mm_and_si128(_mm_clmulepi64_si128(_mm_and_si128(x0, low32), poly_mu, 0x10), low32);
  x0 = _mm_xor_si128(x0, _mm_clmulepi64_si128(q, poly_mu, 0x00));
  return static_cast<std::uint32_t>(_mm_extract_epi32(x0, 1));
}

bool has_clmul() {
  static const bool yes = __builtin_cpu_supports("pclmul") && __builtin_cpu_supports("sse4.1");
  return yes;
}
#endif

}  // namespace crc32_detail

std::uint32_t crc32(std::uint32_t crc, const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
#ifdef SLAMVDB_CRC_CLMUL
  if (size >= 64 && crc32_detail::has_clmul()) {
    const std::size_t folded = size & ~std::size_t{15};
    crc = ~crc32_detail::fold_clmul(~crc, p, folded);
    p += folded;
    size -= folded;
  }
#endif
  return static_cast<std::uint32_t>(::crc32_z(crc, p, size));
}

}  // namespace slamvdb::recording
