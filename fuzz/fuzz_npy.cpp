// Precomputed feature maps (.npy, C x H x W float32 / float16).
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/npy.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::FeatureMap map = slamvdb::read_feature_npy(slamvdb::fuzz::write_input(data, size, "features.npy"));
    if (map.size() != static_cast<std::size_t>(map.dim()) * map.height() * map.width()) __builtin_trap();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
