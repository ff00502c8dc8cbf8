#pragma once
// SplitMix64 finaliser: a bijective 64-bit mix with full avalanche. Seeds the simulator's streams
// and the training's shuffles: the standard library's engines and distributions are
// implementation-defined, and this gives the same numbers with any compiler or library.
#include <cstdint>

namespace slamvdb {

constexpr uint64_t mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

}  // namespace slamvdb
