// TUM trajectories (stamp tx ty tz qx qy qz qw per line), and KITTI ones through the same reader's
// format detection.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/trajectory_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::StampedPoses t = slamvdb::read_trajectory(slamvdb::fuzz::write_input(data, size, "poses.txt"));
    if (t.stamps.size() != t.poses.size()) __builtin_trap();
    for (const slamvdb::Pose& T : t.poses)
      if (!T.matrix().allFinite()) __builtin_trap();  // a pose the reader accepts is finite
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
