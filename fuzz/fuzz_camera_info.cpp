// RELLIS-3D camera_info.txt ("fx fy cx cy" and optionally "k1 k2 p1 p2 k3"), then the camera model
// built from it is validated and used once, as the reader's callers do.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/rellis_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    slamvdb::CameraModel camera =
        slamvdb::read_rellis_camera_info(slamvdb::fuzz::write_input(data, size, "camera_info.txt"), {640, 400});
    camera.validate();
    const slamvdb::CameraModel scaled = camera.scaled(192, 128);
    (void)scaled.project(slamvdb::Vec3d(0.3, -0.2, 5.0));
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
