#pragma once
// Deterministic random numbers for the simulator. The standard library's distributions are
// implementation-defined, so we draw uniforms and Gaussians ourselves: the same seed gives the
// same bytes with any compiler, library or thread count.
#include <cmath>
#include <cstdint>
#include <numbers>

#include "slamvdb/core/mix64.hpp"

namespace slamvdb::synth {

// Independent streams of one seed, e.g. (seed, kLidarNoise, scan index); each consumer of
// randomness gets its own stream so changing one part never shifts another's numbers.
enum class Stream : uint64_t { kTerrain = 1, kLayout, kPath, kLidarNoise, kCameraJitter, kRigError };

class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  Rng(uint64_t seed, Stream stream, uint64_t index)
      : state_(mix64(mix64(seed) ^ mix64(static_cast<uint64_t>(stream) * 0x632be59bd9b4e019ULL + index))) {}

  uint64_t next() { return mix64(state_++); }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  double gaussian() {  // Box-Muller; one value per call keeps the stream position simple
    const double u1 = 1.0 - uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  uint64_t state_;
};

// A hash of a lattice point to [0, 1), for world-fixed texture noise.
inline double lattice_hash(int64_t x, int64_t y, int64_t z) {
  const uint64_t h =
      mix64(static_cast<uint64_t>(x) * 0x9e3779b97f4a7c15ULL ^
            mix64(static_cast<uint64_t>(y) * 0xc2b2ae3d27d4eb4fULL ^ static_cast<uint64_t>(z) * 0x165667b19e3779f9ULL));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

}  // namespace slamvdb::synth
