#pragma once
// Robot recordings read without ROS: ROS 1 bags (v2.0), ROS 2 bags (sqlite3 storage) and MCAP.
// This header is the seam between the two layers of the part:
//   containers (ros1_bag, rosbag2, mcap): where the bytes of each message are, in time order;
//   messages (wire, decoders): what those bytes mean (ROS 1 serialization or CDR).
// A container never decodes a message; a decoder never knows which container the bytes came from.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace slamvdb::recording {

// How a message's bytes are laid out: ROS 1 serialization (little-endian, packed, uint32 length
// prefixes) or OMG CDR as ROS 2 writes it (a 4-byte encapsulation header selecting little- or
// big-endian, natural alignment relative to the end of that header). kOther: a channel of a
// recording that is neither (an MCAP channel in json, protobuf, ...): listed, its messages delivered
// like any other, for the user to skip and count (Channel::encoding says which it is).
enum class Serialization { kRos1, kCdr, kOther };

// One topic of a recording (a ROS 1 connection, a rosbag2 topic, an MCAP channel + schema).
struct Channel {
  std::uint32_t id = 0;  // unique within the recording
  std::string topic;     // "/os1_cloud_node/points"
  // The message type in ROS 1 form, "sensor_msgs/PointCloud2": ROS 2's "sensor_msgs/msg/PointCloud2"
  // is normalised to it, so that decoders are chosen by one name whatever the container.
  std::string type;
  Serialization serialization = Serialization::kRos1;
  // The container's name for the serialization: "ros1", "cdr", or e.g. "json" / "protobuf" (kOther).
  std::string encoding;
  std::string definition;  // the message definition text the recording carries (may be empty)
  // Messages on this channel according to the recording's index or summary (or a first pass over
  // a recording without one, when the reader makes it: an MCAP without summary); nullopt when not
  // known before reading (an unindexed bag).
  std::optional<std::uint64_t> message_count;
};

// One message. `data` stays valid until the next call to RecordingReader::next() (select() does not
// invalidate it).
struct Message {
  const Channel* channel = nullptr;
  std::int64_t log_time_ns = 0;  // when it was recorded (ns since the Unix epoch)
  std::span<const std::uint8_t> data;
  std::uint64_t index = 0;  // 0-based position in the reading order, for messages naming a message
};

struct TimeRange {
  std::int64_t start_ns = 0, end_ns = 0;  // log times of the first and last message
};

// Reads one recording from start to end, message by message in log-time order (equal times in
// the order they were written), with memory bounded by the largest chunk and message, never by the
// recording's size (files over 4 GB work). Damage is an Error naming the file, the offset or
// message and what was wrong (a truncated chunk, a CRC mismatch, an unknown compression); what a
// reader recovers from (a missing index, read linearly) is said in notes().
class RecordingReader {
 public:
  virtual ~RecordingReader() = default;
  // "ROS 1 bag", "ROS 2 bag (sqlite3)", "MCAP", with what matters for a user (compression, profile).
  virtual std::string describe() const = 0;
  virtual const std::vector<Channel>& channels() const = 0;
  // From the index or summary when there is one; nullopt when it is known only after reading.
  virtual std::optional<TimeRange> time_range() const = 0;
  // Total bytes of the recording's files (for progress in MB/s).
  virtual std::uint64_t size_bytes() const = 0;
  // Read only these channels from now on (chunks without any of them may be skipped unread).
  // Empty: all channels (the default).
  virtual void select(const std::set<std::uint32_t>& channel_ids) = 0;
  // The next message in log-time order; false at the end. Throws Error on damage.
  virtual bool next(Message& out) = 0;
  // Bytes of the files consumed so far (for progress).
  virtual std::uint64_t bytes_read() const = 0;
  // Recoveries and assumptions, one line each ("no index: read linearly", ...).
  virtual std::vector<std::string> notes() const = 0;
};

// Whether `path` is a recording this part reads: a .bag file (ROS 1), a .mcap file, a .db3 file or
// a folder holding metadata.yaml and .db3 files (ROS 2); by content (magic bytes), not only by name.
bool is_recording(const std::filesystem::path& path);

// Opens the recording at `path` (any of the forms is_recording accepts). Throws Error naming the
// path when it is none of them or cannot be opened.
std::unique_ptr<RecordingReader> open_recording(const std::filesystem::path& path);

// A ROS 2 type name in ROS 1 form: "sensor_msgs/msg/PointCloud2" (and IDL's
// "sensor_msgs::msg::PointCloud2") -> "sensor_msgs/PointCloud2"; other names unchanged.
std::string ros1_type_name(std::string_view type);

}  // namespace slamvdb::recording
