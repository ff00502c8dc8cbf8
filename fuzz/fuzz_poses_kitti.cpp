// KITTI poses.txt (one row-major 3x4 matrix per line).
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/sequence_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    for (const slamvdb::Pose& T : slamvdb::read_kitti_poses(slamvdb::fuzz::write_input(data, size, "poses.txt")))
      if (!T.matrix().allFinite()) __builtin_trap();  // a pose the reader accepts is finite
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
