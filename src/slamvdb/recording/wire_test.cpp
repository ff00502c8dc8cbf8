// The bounds-checked field reader under the decoders: alignment relative to the CDR header, both
// byte orders, XCDR2's 4-byte alignment of 8-byte values, strings, and errors naming the field.
#include "slamvdb/recording/wire.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "slamvdb/testing/error_of.hpp"

namespace slamvdb::recording {
namespace wire_test {

using testing::error_of;

TEST(WireReader, CdrAlignsRelativeToTheEndOfTheEncapsulationHeader) {
  // CDR_LE: uint8 7, 7 bytes of padding (8-byte alignment counted from byte 4), float64 1.5.
  const std::vector<std::uint8_t> le = {0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xf8, 0x3f};
  WireReader r(le, Serialization::kCdr, "test/Le");
  EXPECT_FALSE(r.big_endian());
  EXPECT_EQ(r.u8("a"), 7);
  EXPECT_EQ(r.f64("b"), 1.5);
  EXPECT_EQ(r.offset(), le.size());
  // CDR_BE, the same fields.
  const std::vector<std::uint8_t> be = {0, 0, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0, 0x3f, 0xf8, 0, 0, 0, 0, 0, 0};
  WireReader b(be, Serialization::kCdr, "test/Be");
  EXPECT_TRUE(b.big_endian());
  EXPECT_EQ(b.u8("a"), 7);
  EXPECT_EQ(b.f64("b"), 1.5);
  // XCDR2 (RTPS numbering 0x07 and rmw's 0x11): 8-byte values are aligned to 4.
  for (const std::uint8_t kind : {0x07, 0x11}) {
    const std::vector<std::uint8_t> cdr2 = {0, kind, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xf8, 0x3f};
    WireReader x(cdr2, Serialization::kCdr, "test/Xcdr2");
    EXPECT_EQ(x.u8("a"), 7);
    EXPECT_EQ(x.f64("b"), 1.5);
  }
  // ROS 1 is packed.
  const std::vector<std::uint8_t> ros1 = {7, 0, 0, 0, 0, 0, 0, 0xf8, 0x3f};
  WireReader p(ros1, Serialization::kRos1, "test/Ros1");
  EXPECT_EQ(p.u8("a"), 7);
  EXPECT_EQ(p.f64("b"), 1.5);
}

TEST(WireReader, StringsInBothSerializations) {
  const std::vector<std::uint8_t> ros1 = {3, 0, 0, 0, 'a', 'b', 'c', 0, 0, 0, 0};
  WireReader r(ros1, Serialization::kRos1, "test/Ros1");
  EXPECT_EQ(r.string("s"), "abc");
  EXPECT_EQ(r.string("empty"), "");
  // CDR counts the NUL; some writers write an empty string as length 0.
  const std::vector<std::uint8_t> cdr = {0, 1, 0, 0, 4, 0, 0, 0, 'a', 'b', 'c', 0, 0, 0, 0, 0, 1, 0, 0, 0, 0};
  WireReader c(cdr, Serialization::kCdr, "test/Cdr");
  EXPECT_EQ(c.string("s"), "abc");
  EXPECT_EQ(c.string("zero"), "");
  EXPECT_EQ(c.string("nul"), "");
  const std::vector<std::uint8_t> unterminated = {0, 1, 0, 0, 3, 0, 0, 0, 'a', 'b', 'c'};
  WireReader u(unterminated, Serialization::kCdr, "test/Cdr");
  EXPECT_NE(error_of([&] { u.string("name"); }).find("field name at byte 8: a CDR string of 3 bytes does not end"),
            std::string::npos);
}

TEST(WireReader, ErrorsNameTheTypeTheFieldPathAndTheOffset) {
  const std::vector<std::uint8_t> bytes = {1, 0, 0, 0, 2, 0};
  WireReader r(bytes, Serialization::kRos1, "pkg/Type");
  EXPECT_EQ(r.sequence_length("items", 1), 1u);
  {
    const WireReader::Scope item(r, "items", 0);
    const WireReader::Scope pose(r, "pose");
    const std::string e = error_of([&] { r.u32("x"); });
    EXPECT_EQ(e, "pkg/Type (ROS 1): field items[0].pose.x at byte 4: needs 4 bytes but the message ends 2 bytes later "
                 "(it is shorter than its fields claim)");
  }
  EXPECT_NE(error_of([&] { r.u32("after"); }).find("field after at byte 4"), std::string::npos) << "the scope ended";
  const std::vector<std::uint8_t> header_only = {0, 1};
  EXPECT_NE(error_of([&] { WireReader(header_only, Serialization::kCdr, "pkg/Type"); })
                .find("field CDR encapsulation header at byte 0: the message has only 2 bytes"),
            std::string::npos);
}

}  // namespace wire_test
}  // namespace slamvdb::recording
