// Camera and label images (PNG / JPEG): the header parser, and loading with the size checks
// before decoding. The limit is small here (4 MP) so the fuzzer does not spend its time decoding.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const auto header = slamvdb::parse_image_header(bytes);
  try {
    slamvdb::ImageRecord record;
    record.rgb = slamvdb::fuzz::write_input(data, size, "image.jpg");
    record.labels = record.rgb;
    const slamvdb::ImageFrame frame = slamvdb::load_image_frame(record, true, true, 4'000'000);
    // Anything decoded has the size its header announced.
    if (!header || frame.rgb.size() != *header || frame.labels.size() != *header) __builtin_trap();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
