// KITTI calib.txt (P2 and Tr), and the camera pose derived from it.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/kitti_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const slamvdb::KittiCalib calib = slamvdb::read_kitti_calib(slamvdb::fuzz::write_input(data, size, "calib.txt"));
    (void)slamvdb::kitti_T_lidar_camera(calib);
    slamvdb::kitti_camera(calib, 1241, 376).validate();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
