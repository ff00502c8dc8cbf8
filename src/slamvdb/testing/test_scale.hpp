#pragma once
// For tests only: how large the heaviest tests' simulated drives are.
// The sanitizer run of the suite (scripts/test_asan.sh exports SLAMVDB_TEST_SCALE=sanitizer) gives
// the few tests that simulate and register long LiDAR drives a shorter part of the same drive:
// under ASan + UBSan the synthetic ray casting and the ICP's Eigen code run 10-25x slower than in
// Release, and those few tests alone took most of the sanitizer run. A memory error or undefined
// behaviour shows on 40 scans as on 200; the accuracy over the full drive is the Release suite's
// job, which always runs the full size. The same assertions hold at both sizes (the Release suite
// can run the small size too: SLAMVDB_TEST_SCALE=sanitizer ctest ...).
#include <cstdlib>
#include <string_view>

namespace slamvdb::testing {

inline bool sanitizer_test_scale() {
  const char* scale = std::getenv("SLAMVDB_TEST_SCALE");
  return scale != nullptr && std::string_view(scale) == "sanitizer";
}

// `full` in the Release suite, `small` in the sanitizer run.
template <class T>
T test_size(T full, T small) {
  return sanitizer_test_scale() ? small : full;
}

}  // namespace slamvdb::testing
