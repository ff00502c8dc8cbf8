// Names that carry data: RELLIS-3D image stems (frame number and time stamp), and the escaping
// of any text before it is printed.
#include <cmath>

#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/io/rellis_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  if (const auto name = slamvdb::parse_rellis_image_name(text))
    if (!std::isfinite(name->stamp) || name->frame < 0) __builtin_trap();
  const std::string escaped = slamvdb::escape_control(text);
  // No C0 control or DEL byte, and no C1 control (U+0080..U+009F, C2 80..C2 9F in UTF-8) is left.
  for (std::size_t i = 0; i < escaped.size(); ++i) {
    const auto b = static_cast<unsigned char>(escaped[i]);
    if (b < 0x20 || b == 0x7f) __builtin_trap();
    if (b == 0xc2 && i + 1 < escaped.size() && static_cast<unsigned char>(escaped[i + 1]) <= 0x9f &&
        static_cast<unsigned char>(escaped[i + 1]) >= 0x80)
      __builtin_trap();
  }
  return 0;
}
