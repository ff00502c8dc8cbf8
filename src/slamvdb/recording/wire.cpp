#include "slamvdb/recording/wire.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb::recording {

namespace wire_detail {

// The encapsulation kinds of the RTPS specification (the second byte of the header).
constexpr std::uint8_t kCdrBe = 0x00, kCdrLe = 0x01, kPlCdrBe = 0x02, kPlCdrLe = 0x03, kCdr2Be = 0x10,
                       kCdr2Le = 0x11, kPlCdr2Be = 0x12, kPlCdr2Le = 0x13, kDCdr2Be = 0x14, kDCdr2Le = 0x15;
// XCDR2 has a second numbering (RTPS 2.5: 0x06..0x0b, delimited before parameter-list); both are
// accepted, as @foxglove/cdr does.
constexpr std::uint8_t kCdr2BeAlt = 0x06, kCdr2LeAlt = 0x07, kDCdr2BeAlt = 0x08, kDCdr2LeAlt = 0x09,
                       kPlCdr2BeAlt = 0x0a, kPlCdr2LeAlt = 0x0b;

}  // namespace wire_detail

WireReader::WireReader(std::span<const std::uint8_t> bytes, Serialization serialization, std::string_view type)
    : bytes_(bytes), serialization_(serialization), type_(type) {
  using namespace wire_detail;
  if (serialization_ == Serialization::kRos1) return;
  if (serialization_ == Serialization::kOther)
    fail("message", "its encoding is neither ROS 1 serialization nor CDR (a json or protobuf channel): no ROS decoder reads it");
  if (bytes_.size() < 4) fail("CDR encapsulation header", fmt::format("the message has only {} bytes", bytes_.size()));
  const std::uint8_t kind = bytes_[1];
  switch (kind) {
    case kCdrBe: big_endian_ = true; max_alignment_ = 8; break;
    case kCdrLe: big_endian_ = false; max_alignment_ = 8; break;
    case kCdr2Be: case kCdr2BeAlt: big_endian_ = true; max_alignment_ = 4; break;
    case kCdr2Le: case kCdr2LeAlt: big_endian_ = false; max_alignment_ = 4; break;
    case kPlCdrBe: case kPlCdrLe: case kPlCdr2Be: case kPlCdr2Le: case kPlCdr2BeAlt: case kPlCdr2LeAlt:
      fail("CDR encapsulation header",
           fmt::format("encapsulation kind {:#04x} is a parameter-list encoding (PL_CDR), which ROS messages never use",
                       kind));
    case kDCdr2Be: case kDCdr2Le: case kDCdr2BeAlt: case kDCdr2LeAlt:
      fail("CDR encapsulation header",
           fmt::format("encapsulation kind {:#04x} (delimited XCDR2, for appendable types) is not supported", kind));
    default: fail("CDR encapsulation header", fmt::format("unknown encapsulation kind {:#04x}", kind));
  }
  if (bytes_[0] != 0)
    fail("CDR encapsulation header", fmt::format("its first byte is {:#04x}, not 0", bytes_[0]));
  pos_ = origin_ = 4;
}

WireReader::Scope::Scope(WireReader& reader, std::string_view name, std::int64_t index) : reader_(reader) {
  if (reader_.depth_ < static_cast<int>(std::size(reader_.path_))) reader_.path_[reader_.depth_] = {name, index};
  ++reader_.depth_;
}

WireReader::Scope::~Scope() { --reader_.depth_; }

void WireReader::fail_at(std::size_t offset, std::string_view field, std::string_view what) const {
  std::string path;
  const int shown = std::min<int>(depth_, static_cast<int>(std::size(path_)));
  for (int i = 0; i < shown; ++i) {
    path += path_[i].name;
    if (path_[i].index >= 0) path += fmt::format("[{}]", path_[i].index);
    path += '.';
  }
  path += field;
  throw Error(fmt::format("{} ({}): field {} at byte {}: {}", type_,
                          serialization_ == Serialization::kRos1 ? "ROS 1" : (big_endian_ ? "CDR big-endian" : "CDR"),
                          path, offset, what));
}

void WireReader::fail_short(std::size_t bytes, std::string_view field) const {
  fail(field, fmt::format("needs {} bytes but the message ends {} bytes later (it is shorter than its fields claim)",
                          bytes, bytes_.size() - pos_));
}

void WireReader::align(std::size_t alignment, std::string_view field) {
  if (serialization_ == Serialization::kRos1 || alignment <= 1) return;
  const std::size_t misalignment = (pos_ - origin_) % alignment;
  if (misalignment == 0) return;
  need(alignment - misalignment, field);
  pos_ += alignment - misalignment;
}

std::int64_t WireReader::time_ns(std::string_view field) {
  std::int64_t sec = 0;
  if (serialization_ == Serialization::kRos1)
    sec = u32(field);
  else
    sec = i32(field);
  const std::uint32_t nsec = u32(field);
  return sec * 1'000'000'000 + static_cast<std::int64_t>(nsec);
}

std::string_view WireReader::string(std::string_view field) {
  const std::uint32_t length = u32(field);
  need(length, field);
  const char* text = reinterpret_cast<const char*>(bytes_.data() + pos_);
  if (serialization_ == Serialization::kCdr && length > 0) {
    // CDR counts the terminating NUL; an empty string is written with length 1 (some writers 0).
    if (text[length - 1] != '\0') fail(field, fmt::format("a CDR string of {} bytes does not end with a NUL", length));
    pos_ += length;
    return {text, length - 1};
  }
  pos_ += length;
  return {text, length};
}

std::uint32_t WireReader::sequence_length(std::string_view field, std::size_t min_element_bytes) {
  const std::size_t at = pos_;
  const std::uint32_t count = u32(field);
  if (min_element_bytes > 0 && count > remaining() / min_element_bytes) {
    pos_ = at;
    fail(field, fmt::format("a sequence of {} elements of at least {} bytes cannot fit in the {} bytes left", count,
                            min_element_bytes, remaining() - 4));
  }
  return count;
}

std::span<const std::uint8_t> WireReader::byte_sequence(std::string_view field) {
  const std::uint32_t length = u32(field);
  need(length, field);
  const auto view = bytes_.subspan(pos_, length);
  pos_ += length;
  return view;
}

void WireReader::f64_array(std::string_view field, std::span<double> out) {
  for (double& value : out) value = f64(field);
}

void WireReader::expect_end() {
  // CDR writers may pad the end to a multiple of 4 bytes.
  const std::size_t left = remaining();
  if (left == 0 || (serialization_ == Serialization::kCdr && left < 4)) return;
  fail("(end)", fmt::format("{} bytes are left after the last field (is the message of another type?)", left));
}

}  // namespace slamvdb::recording
