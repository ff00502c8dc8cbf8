#pragma once
// The bytes of one serialized ROS message, read field by field with every read bounds-checked:
// ROS 1 serialization (little-endian, packed, strings and sequences prefixed by a uint32 length)
// or CDR as ROS 2 writes it (a 4-byte encapsulation header choosing the byte order; natural
// alignment of every primitive relative to the end of that header; strings carry a NUL counted in
// their length). A read past the end, an absurd sequence count or a malformed string throws an
// Error naming the message type, the field and its offset.
//
// Hand-written rather than eProsima Fast-CDR (libfastcdr-dev 1.0): Fast-CDR reads CDR only (ROS 1
// needs a reader anyway), copies sequences into std::vector where PointCloud2 and Image need a
// view of their payload, and its exceptions say "not enough memory" without the field or offset.
// Reading the dozen types slamvdb uses takes these ~250 lines.
#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>

#include "slamvdb/recording/recording.hpp"

namespace slamvdb::recording {

class WireReader {
 public:
  // `type` names the message in errors ("sensor_msgs/PointCloud2"). For CDR, reads and checks the
  // encapsulation header (CDR_BE, CDR_LE and their XCDR2 forms; parameter-list encodings are an
  // Error: ROS messages are final types, never written so).
  WireReader(std::span<const std::uint8_t> bytes, Serialization serialization, std::string_view type);

  Serialization serialization() const { return serialization_; }
  bool big_endian() const { return big_endian_; }
  std::size_t offset() const { return pos_; }  // from the first byte of the message
  std::size_t remaining() const { return bytes_.size() - pos_; }
  std::string_view type() const { return type_; }

  // Field paths for errors: a decoder of a nested message enters it ("header", "transforms", 3)
  // and leaves it when the Scope ends; errors then read "transforms[3].header.stamp".
  class Scope {
   public:
    Scope(WireReader& reader, std::string_view name, std::int64_t index = -1);
    ~Scope();
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    WireReader& reader_;
  };

  bool boolean(std::string_view field) { return u8(field) != 0; }
  std::uint8_t u8(std::string_view field) { return primitive<std::uint8_t>(field); }
  std::int8_t i8(std::string_view field) { return primitive<std::int8_t>(field); }
  std::uint16_t u16(std::string_view field) { return primitive<std::uint16_t>(field); }
  std::int16_t i16(std::string_view field) { return primitive<std::int16_t>(field); }
  std::uint32_t u32(std::string_view field) { return primitive<std::uint32_t>(field); }
  std::int32_t i32(std::string_view field) { return primitive<std::int32_t>(field); }
  std::uint64_t u64(std::string_view field) { return primitive<std::uint64_t>(field); }
  std::int64_t i64(std::string_view field) { return primitive<std::int64_t>(field); }
  float f32(std::string_view field) { return primitive<float>(field); }
  double f64(std::string_view field) { return primitive<double>(field); }

  // A time (ROS 1: uint32 sec, uint32 nsec; ROS 2 builtin_interfaces/Time: int32 sec, uint32
  // nanosec) as nanoseconds since the epoch.
  std::int64_t time_ns(std::string_view field);
  // A string; the view points into the message bytes.
  std::string_view string(std::string_view field);
  // The element count of a sequence, checked against the bytes left: each element takes at least
  // `min_element_bytes`, so an absurd count is an Error before anything is allocated for it.
  std::uint32_t sequence_length(std::string_view field, std::size_t min_element_bytes);
  // uint8[] (with its length prefix): a view of the payload.
  std::span<const std::uint8_t> byte_sequence(std::string_view field);
  // float64[N] (fixed size, no prefix) and float64[] (prefixed) into `out`.
  void f64_array(std::string_view field, std::span<double> out);

  // Throws the Error for `field` at the current offset, or at `offset` (a field read earlier).
  [[noreturn]] void fail(std::string_view field, std::string_view what) const { fail_at(pos_, field, what); }
  [[noreturn]] void fail_at(std::size_t offset, std::string_view field, std::string_view what) const;
  // Throws unless every byte was read (trailing bytes mean the type or layout is not what the
  // decoder thinks: a wrong type name in the recording).
  void expect_end();

 private:
  template <typename T>
  T primitive(std::string_view field) {
    align(sizeof(T) == 8 ? max_alignment_ : sizeof(T), field);
    need(sizeof(T), field);
    T value;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    if (big_endian_ && sizeof(T) > 1) value = byteswap(value);
    pos_ += sizeof(T);
    return value;
  }
  template <typename T>
  static T byteswap(T value) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &value, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&value, b, sizeof(T));
    return value;
  }
  void align(std::size_t alignment, std::string_view field);
  void need(std::size_t bytes, std::string_view field) {
    if (bytes > bytes_.size() - pos_) fail_short(bytes, field);
  }
  [[noreturn]] void fail_short(std::size_t bytes, std::string_view field) const;

  std::span<const std::uint8_t> bytes_;
  Serialization serialization_;
  std::string_view type_;
  bool big_endian_ = false;
  std::size_t pos_ = 0;
  std::size_t origin_ = 0;         // CDR: alignment is relative to the end of the encapsulation header
  std::size_t max_alignment_ = 1;  // ROS 1: packed; CDR: 8 (XCDR2: 4)
  struct PathPart {
    std::string_view name;
    std::int64_t index;
  };
  PathPart path_[8];
  int depth_ = 0;
};

}  // namespace slamvdb::recording
