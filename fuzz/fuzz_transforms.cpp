// RELLIS-3D transforms.yaml (T_lidar_camera as q and t): YAML parsing included.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/rellis_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::Pose T = slamvdb::read_rellis_transforms(slamvdb::fuzz::write_input(data, size, "transforms.yaml"));
    if (!T.matrix().allFinite()) __builtin_trap();  // accepted extrinsics are finite
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
