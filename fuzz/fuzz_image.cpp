// Camera and label images (PNG / JPEG): the header parser, and loading with the size checks
// before decoding, as a camera image and as a label image. The limit is small here (4 MP) so the
// fuzzer does not spend its time decoding.
#include "fuzz_file.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/io/image_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const auto header = slamvdb::parse_image_header(bytes);
  slamvdb::ImageRecord record;
  record.rgb = record.labels = slamvdb::fuzz::write_input(data, size, "image.jpg");
  for (const bool as_labels : {false, true}) {
    try {
      const slamvdb::ImageFrame frame = slamvdb::load_image_frame(record, !as_labels, as_labels, 4'000'000);
      // Anything decoded has the size its header announced, and the type asked for.
      const cv::Mat& image = as_labels ? frame.labels : frame.rgb;
      if (!header || image.size() != *header || image.type() != (as_labels ? CV_8UC1 : CV_8UC3)) __builtin_trap();
    } catch (const slamvdb::Error&) {
    }
  }
  return 0;
}
